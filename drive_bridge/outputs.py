"""Writing the files the tool leaves behind (log.csv, meta.yaml, JSON results, reports): each to
a temporary name beside it, then renamed, so a file is either complete or absent -- whatever
stops the process (an exception, Ctrl-C, SIGTERM) while it is written."""
from __future__ import annotations

import json
import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path


@contextmanager
def atomic(path: str | Path) -> Iterator[Path]:
    """A temporary path to write ``path``'s content to; renamed to ``path`` when the block ends
    normally, removed otherwise."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp")
    try:
        yield tmp
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()


def write_text(path: str | Path, text: str) -> Path:
    with atomic(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return Path(path)


SCHEMA_VERSION = 1


def stamped(name: str, doc: dict) -> dict:
    """``doc`` opening with ``schema`` ("drive-bridge/<name>") and ``schema_version``: the JSON
    Schema it follows ships as ``drive_bridge/data/schemas/<name>.schema.json``."""
    return {"schema": f"drive-bridge/{name}", "schema_version": SCHEMA_VERSION, **doc}


def write_json(path: str | Path, doc) -> Path:
    return write_text(path, json.dumps(doc, indent=1, default=float))
