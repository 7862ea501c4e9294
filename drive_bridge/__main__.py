"""``python -m drive_bridge``: the drive-bridge command line."""

import sys

from .cli import main

sys.exit(main())
