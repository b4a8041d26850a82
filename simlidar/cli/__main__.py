"""``python -m simlidar.cli``."""

import sys

from simlidar.cli import main

sys.exit(main())
