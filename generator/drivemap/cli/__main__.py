"""``python -m drivemap.cli``."""

import sys

from drivemap.cli import main

sys.exit(main())
