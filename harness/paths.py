"""Where the tests find the repository and ``../shared`` beside it: no library imported, so that a
test run's controlling process (pytest-xdist's, which runs no test) reads them without loading the
simulator."""

from __future__ import annotations

import os
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared"
VENDOR_EDS = Path(os.environ.get("DRIVE_BRIDGE_VENDOR_EDS", SHARED / "eds-vendor"))
