"""``python -m jaxgait.train``."""

import sys

from jaxgait.train.cli import main

sys.exit(main())
