"""History records made by hand (not by a commissioning): drives, times and parameters as a test
sets them."""

from __future__ import annotations

import uuid
from datetime import datetime, timedelta, timezone

from drive_bridge.history.record import SCHEMA, SCHEMA_VERSION

T0 = datetime(2026, 3, 2, 8, 0, tzinfo=timezone.utc)
VENDOR, PRODUCT = 0x9A, 0x4711
UNITS = {"J": "kg·m²", "c0": "Nm", "c1": "Nm·s/rad"}


def day(n: float) -> datetime:
    return T0 + timedelta(days=n)


def axis(name: str, serial: int | None, params: dict[str, tuple], product: int = PRODUCT) -> dict:
    """An axis entry: ``params`` name -> (value, std) or (value, std, determined)."""
    return {
        "axis": name,
        "node_id": 1,
        "verdict": "PASS",
        "consistent": True,
        "stored": True,
        "drive": None
        if serial is None
        else {
            "vendor_id": f"0x{VENDOR:08X}",
            "product_code": f"0x{product:08X}",
            "revision": "0x00000001",
            "serial": f"0x{serial:08X}",
        },
        "parameters": {
            k: {
                "value": v[0],
                "std": v[1],
                "unit": UNITS.get(k, ""),
                "determined": v[2] if len(v) > 2 else True,
            }
            for k, v in params.items()
        },
    }


def record(
    when: datetime,
    axes: list[dict],
    run_id: str | None = None,
    simulated: bool = False,
    updated: datetime | None = None,
) -> dict:
    return {
        "schema": SCHEMA,
        "schema_version": SCHEMA_VERSION,
        "run_id": run_id or uuid.uuid4().hex,
        "kind": "commission",
        "started": when.isoformat(),
        "updated": (updated or when).isoformat(),
        "version": "test",
        "config": {"path": "/plant/cell4/bus.yml", "sha256": "0" * 64},
        "out": "/plant/runs/x",
        "status": "ok",
        "verdict": "PASS",
        "simulated": simulated,
        "failed": None,
        "axes": axes,
    }


def nominal(scale_c0: float = 1.0) -> dict[str, tuple]:
    """The paper's Y axis, identified with 0.5 % std."""
    return {"J": (1.0e-4, 5e-7), "c0": (0.323 * scale_c0, 1.6e-3), "c1": (5.0e-4, 2.5e-6)}
