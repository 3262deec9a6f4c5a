import os
from pathlib import Path

import pytest

# One XLA compilation cache for the whole test session: test files that build the same
# rollout share the compiled program instead of compiling it again.
os.environ.setdefault("JAXGAIT_CACHE_DIR", str(Path(__file__).resolve().parents[1] / ".jax_cache"))

from jaxgait import models  # noqa: E402
from jaxgait.core import compile_cache  # noqa: E402

compile_cache.enable()


@pytest.fixture(scope="session")
def fbl_model():
    return models.get_model("fbl")
