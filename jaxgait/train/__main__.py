import sys

from jaxgait.train.loop import main

sys.exit(main())
