"""Reading EDS/DCF files with canopen, around the traps of real vendor files."""
from __future__ import annotations

import io
from pathlib import Path

import canopen

from .errors import ConfigError


def load_od(path: str | Path, node_id: int) -> canopen.ObjectDictionary:
    """Import an EDS or DCF; files that are not UTF-8 are read as Windows-1252.

    Raises ConfigError naming the file when canopen cannot parse it.
    """
    path = Path(path)
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise ConfigError(path, "", f"cannot read EDS/DCF: {exc.strerror}") from exc
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        text = raw.decode("cp1252", errors="replace")
    source = io.StringIO(text)
    source.name = str(path)
    try:
        return canopen.import_od(source, node_id)
    except Exception as exc:  # canopen raises bare parser errors of several kinds
        raise ConfigError(path, "", f"not a readable EDS/DCF: {exc}") from exc
