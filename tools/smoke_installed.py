"""Smoke test of drive-bridge as installed from its wheel (run with that environment's python,
from outside the source tree; tools/check_wheel.sh does it): the package is the installed one,
every file it ships is there and readable, and a commission run left a complete result.

    python tools/smoke_installed.py RUN_DIR
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import drive_bridge
from drive_bridge.config import load_bus_config
from drive_bridge.ident import identify
from drive_bridge.params.profile import available, load_profile
from drive_bridge.resources import DEFAULT_BUS_CONFIG, PROJECT_EDS, vendor_dir
from drive_bridge.sim.robot_config import DEFAULT_CONFIG, load_sim_config


def main(run: Path) -> None:
    package = Path(drive_bridge.__file__).resolve().parent
    assert "site-packages" in package.parts, f"drive_bridge imported from {package}, not an installed wheel"
    assert PROJECT_EDS.is_file() and package in PROJECT_EDS.resolve().parents
    config = load_bus_config(DEFAULT_BUS_CONFIG)
    assert list(config.nodes) == ["x", "y", "z"]
    assert len(load_sim_config(DEFAULT_CONFIG).axes) == 3
    shipped = available()
    assert "drive_bridge_servo" in shipped and len(shipped) >= 4, shipped
    for name in shipped:
        if name == "drive_bridge_servo" or vendor_dir().is_dir():
            load_profile(name)
    summary = json.loads((run / "summary.json").read_text())
    assert summary["status"] == "ok", summary.get("failed")
    assert (run / "report.html").stat().st_size > 10_000
    results = identify(run / "campaign", seed=0)
    assert set(results) == {"x", "y", "z"}
    print(
        f"installed drive-bridge {drive_bridge.__version__} at {package}: {len(shipped)} profiles, "
        f"commission status {summary['status']}, identify ok"
    )


if __name__ == "__main__":
    main(Path(sys.argv[1]))
