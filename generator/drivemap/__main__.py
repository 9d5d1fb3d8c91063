import sys

from drivemap.cli import main

sys.exit(main())
