import os

os.environ.setdefault("XLA_FLAGS", "--xla_cpu_multi_thread_eigen=false")

import pytest  # noqa: E402


@pytest.fixture(scope="session")
def fbl_model():
    from jaxgait import sim

    return sim.make_model()
