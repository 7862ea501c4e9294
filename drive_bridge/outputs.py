"""Writing the JSON files the steps leave behind (tune.json, write.json, summary.json, ...):
to a temporary name beside the file, then renamed, so a file is either complete or absent."""
from __future__ import annotations

import json
import os
from pathlib import Path


def write_json(path: str | Path, doc) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(doc, indent=1, default=float))
    os.replace(tmp, path)
    return path
