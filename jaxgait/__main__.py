"""``python -m jaxgait``: the ``jaxgait`` command (:mod:`jaxgait.cli`)."""

import sys

from jaxgait.cli import console_main

sys.exit(console_main())
