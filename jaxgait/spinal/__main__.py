import sys

from jaxgait.spinal.cli import main

sys.exit(main())
