"""``python -m jaxgait.train`` (the host devices are set by the package, see its
``__init__``)."""

import sys

from jaxgait.train.cli import main

sys.exit(main())
