"""``python -m jaxgait``: the ``jaxgait`` command (:mod:`jaxgait.cli`)."""

import sys

from jaxgait.cli import main

sys.exit(main())
