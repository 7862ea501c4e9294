"""``python -m drive_bridge``: the drive-bridge command line."""

import sys

from .cli import main

if __name__ == "__main__":  # (not again in a worker process spawned from it)
    sys.exit(main())
