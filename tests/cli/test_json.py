"""``--json`` on every command: one object on stdout that follows the schema shipped for it, with
object addresses, identities and COB-IDs as hex strings and floats rounded to what they mean."""

from __future__ import annotations

import json

import pytest

from drive_bridge.cli import main
from harness.paths import VENDOR_EDS
from harness.support import EDS, follows_schema

pytestmark = pytest.mark.slow

pytest.importorskip("jsonschema")


def _printed(capsys) -> dict:
    out = capsys.readouterr().out
    assert out.count("\n") == 1, out  # exactly one JSON object, nothing else on stdout
    return json.loads(out)


def test_scan_names_identities_in_hex(capsys):
    assert main(["scan", "--sim", "--json"]) == 0
    doc = follows_schema(_printed(capsys), "scan")
    assert doc["found"]["x"]["vendor_id"] == "0x00000DB1" and doc["found"]["x"]["device_type"] == "0x00020192"
    assert doc["found"]["x"]["node_id"] == 1


def test_record_then_decode_then_identify(tmp_path, capsys):
    assert main(["record", "--sim", "--quick", "--axes", "y", "--out", str(tmp_path), "--json"]) == 0
    rec = follows_schema(_printed(capsys), "record")
    assert (
        rec["aborted"] is None and rec["axes"]["y"]["samples"] > 500 and rec["timing"]["clock"] == "lockstep"
    )
    assert main(["decode", str(tmp_path / "trace.blf"), "--json"]) == 0
    dec = follows_schema(_printed(capsys), "decode")
    assert (
        dec["problem"] is None
        and dec["rows"] >= rec["axes"]["y"]["samples"]
        and (tmp_path / "decoded.csv").is_file()
    )
    assert main(["identify", str(tmp_path), "--json"]) == 0
    ident = follows_schema(_printed(capsys), "identify")
    assert ident["axes"]["y"]["params"]["J"] > 0


def test_check_eds_and_export(tmp_path, capsys):
    assert main(["check-eds", str(EDS), "--json"]) == 0
    doc = follows_schema(_printed(capsys), "check-eds")
    assert doc["standard"] and doc["files"][0]["path"] == str(EDS)
    code = main(["check-eds", str(VENDOR_EDS / "pilz_prbt_0_1.dcf"), "--json"])
    doc = follows_schema(_printed(capsys), "check-eds")
    assert code == (0 if doc["standard"] else 1)  # 1 where Lely's dcfchk is installed
    assert any(line.startswith("modes (0x6502): profile position (1)") for line in doc["files"][0]["drive"])
    assert main(["export", "ros2", "--out", str(tmp_path), "--json"]) == 0
    doc = follows_schema(_printed(capsys), "export")
    assert "bus.yml" in doc["files"] and all((tmp_path / f).is_file() for f in doc["files"])


def test_verbose_shows_drive_bridge_log_lines_and_quiet_only_errors(tmp_path, capsys):
    """-v: drive-bridge's log (bring-up, enabling, stopping) on stderr; by default and with -q, none;
    python-can's and canopen's lines only with -vv."""
    from drive_bridge.cli import main

    args = ["record", "--sim", "--quick", "--axes", "y", "--out"]
    assert main(["-v"] + args + [str(tmp_path / "a")]) == 0
    err = capsys.readouterr().err
    assert (
        "INFO drive_bridge.master.bringup: axis y: units" in err and "INFO drive_bridge.master.stream" in err
    )
    assert " canopen." not in err  # python-can's and canopen's: -vv
    assert main(["-vv"] + args + [str(tmp_path / "d")]) == 0
    assert "INFO canopen.pdo" in capsys.readouterr().err
    assert main(args + [str(tmp_path / "b")]) == 0
    assert " INFO " not in capsys.readouterr().err
    assert main(["-q"] + args + [str(tmp_path / "c")]) == 0
    assert " INFO " not in capsys.readouterr().err


def test_a_command_leaves_the_loggers_as_it_found_them(caplog):
    """main() may run again in the same process (the API, a test after another): -q or -vv in one
    command leaves no level behind that silences, or opens up, the next one's log."""
    import logging

    from drive_bridge.cli import LIBRARY_LOGGERS, main

    names = ("drive_bridge", *LIBRARY_LOGGERS)
    before = [logging.getLogger(name).level for name in names]
    for flag in ("-q", "-vv"):
        assert main([flag, "scan", "--sim"]) == 0
        assert [logging.getLogger(name).level for name in names] == before
    with caplog.at_level(logging.WARNING):
        logging.getLogger("drive_bridge.monitor.listen").warning("after -q: still said")
    assert "after -q: still said" in caplog.text
