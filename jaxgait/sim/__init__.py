"""Layer 5: one pure step of body + muscles + controller + contact, and rollouts."""

from jaxgait.sim.step import *  # noqa: F401,F403
from jaxgait.sim.step import _limit_rows, _log_row, _record_touchdowns  # noqa: F401
