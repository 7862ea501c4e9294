"""Property-based fuzzing of every reader (bounded: seconds): an input is accepted, or refused with
one clear DriveBridgeError -- never a traceback of another kind."""

from __future__ import annotations

import tempfile
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings

from drive_bridge.errors import DriveBridgeError
from harness.fuzzing import kinds, record_trace

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def trace(tmp_path_factory):
    return record_trace(tmp_path_factory.mktemp("trace"))


KINDS = kinds(b"", "")  # names only; the trace kind is rebuilt with the real trace


@pytest.mark.parametrize("name", list(KINDS))
def test_every_reader_accepts_or_refuses_cleanly(name, trace, capsys):
    kind = kinds(*trace)[name]

    @settings(
        max_examples=8 if name == "identify (log)" else 40,
        deadline=None,
        database=None,
        derandomize=True,
        suppress_health_check=list(HealthCheck),
    )
    @given(kind.strategy)
    def check(value):
        with tempfile.TemporaryDirectory() as tmp:
            work = Path(tmp) / "in"
            work.mkdir()
            try:
                kind.read(value, work)
            except DriveBridgeError as exc:
                assert str(exc).strip() and "\n" not in str(exc).strip(), "one line"

    check()
    capsys.readouterr()
