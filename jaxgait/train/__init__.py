"""Layer 11: objectives, the experiment registry, checkpoints and the training loop."""

from jaxgait.train.loop import *  # noqa: F401,F403
from jaxgait.train.loop import _batched_rollout, _scorer  # noqa: F401
