"""jaxgait: neuromuscular locomotion in JAX + MuJoCo MJX (see README.md)."""

from jaxgait.core import quiet_import as _quiet_import

_quiet_import.install()
