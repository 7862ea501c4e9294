"""Scan and bring-up against the simulated robot."""
from __future__ import annotations

from drive_bridge.cli import main

from ..support import bus_yml_beside


def test_scan_lists_the_three_drives(capsys):
    assert main(["scan", "--sim"]) == 0
    out = capsys.readouterr().out
    for node_id, axis in ((1, "x"), (2, "y"), (3, "z")):
        assert f"node   {node_id}  axis {axis}" in out and "CiA 402 drive" in out


def test_scan_reports_missing_and_unexpected_nodes(tmp_path, capsys):
    cfg = bus_yml_beside(tmp_path, "node_id: 3", "node_id: 9")
    assert main(["scan", "--sim", "--config", str(cfg)]) == 3
    out = capsys.readouterr().out
    assert "axis z    MISSING" in out and "node   3  not configured" in out
