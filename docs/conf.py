"""Sphinx configuration of drive-bridge's documentation (MyST Markdown; ``sphinx-build -W`` in CI)."""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent / "_ext"))

from drive_bridge import __version__  # noqa: E402

project = "drive-bridge"
author = "the drive-bridge authors"
copyright = "2026, the drive-bridge authors"
release = version = __version__
extensions = ["myst_parser", "sphinx.ext.autodoc", "drive_bridge_docs"]
source_suffix = {".md": "markdown"}
exclude_patterns = ["_build"]
myst_heading_anchors = 3
myst_enable_extensions = ["colon_fence"]
suppress_warnings = ["myst.header"]  # the moved README sections start one level down
html_theme = "alabaster"
html_static_path: list[str] = []
autodoc_member_order = "bysource"
nitpicky = False
