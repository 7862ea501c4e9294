"""The bus as ros2_canopen and Lely's dcfgen take it: ``drive-bridge export ros2``.

Writes ``bus.yml`` in ros2_canopen's format and one DCF per node beside it:

* ``options.dcf_path`` is the directory itself; ``master`` has the master's node-ID, the
  baudrate [kbit/s] and the SYNC period [µs], with ros2_canopen's master driver;
* each node, under ``nodes`` and with no ``defaults`` (ros2_canopen's cogen writes ``defaults``
  over a node's own entries: with none, nothing is lost), has its node-ID, its DCF, the CiA 402
  driver, ``period`` [ms], ``position_mode`` (8 cyclic synchronous position, 7 interpolated
  position), ``scale_pos_to_dev`` / ``scale_pos_from_dev`` (device increments per rad or m), its
  heartbeat, every PDO (``enabled``, ``cob_id: auto`` or its number, ``transmission``,
  ``mapping``; the drive's other PDOs 1-4 ``enabled: false``) and as ``sdo`` what drive-bridge's
  bring-up writes (interpolation period, following-error window, software limits, the node's
  own ``sdo`` list), so Lely's master configures the node as drive-bridge does;
* drive-bridge's own keys (``scaling``, ``limits``, ``profile``, ``motor``) stay in each node
  (dcfgen and ros2_canopen skip what they do not know); the campaign is drive-bridge's alone and
  is not written.

The DCFs describe the devices (their object dictionaries, CiA 306 clean: Lely's dcfchk passes
them), with the node-ID and bitrate in ``[DeviceComissioning]`` and no ParameterValue: the
configuration is the bus.yml's, which dcfgen turns into the SDOs the master sends at boot.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from .cia.dcf import write_dcf
from .cia.objects import (
    CYCLE_PERIOD,
    HEARTBEAT_PRODUCER,
    RPDO_COMMUNICATION,
    TARGET_POSITION,
    TPDO_COMMUNICATION,
)
from .config import BusConfig, MasterConfig, NodeConfig, PdoConfig
from .errors import UserError
from .master.bringup import settings


class Hex(int):
    """An int written as 0x... (object indices, COB-IDs: how CANopen engineers read them)."""


class _Dumper(yaml.SafeDumper):
    pass


_Dumper.add_representer(Hex, lambda d, v: d.represent_scalar("tag:yaml.org,2002:int", f"0x{int(v):04X}"))

OWN_KEYS = (
    "scaling",
    "limits",
    "profile",
    "motor",
    "following_error_window_rad",
    "holding",
    "hold_tolerance_rad",
    "hold_tolerance_m",
)
MASTER_NODE_ID = 127


def export(config: BusConfig, out: str | Path) -> list[Path]:
    """Write ``bus.yml`` and ``<axis>.dcf`` for every node of ``config`` into ``out``.

    Parameters
    ----------
    config : BusConfig
        The bus configuration.
    out : str or Path
        The directory.

    Returns
    -------
    list of Path
        The files written.
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    m = config.master
    doc: dict[str, Any] = {
        "options": {"dcf_path": "."},
        "master": {
            "node_id": m.node_id or MASTER_NODE_ID,
            "driver": "ros2_canopen::MasterDriver",
            "package": "canopen_master_driver",
            "baudrate": m.nominal_bitrate // 1000,
            "sync_period": round(m.sync_period_s * 1e6),
            "heartbeat_consumer": True,
            # the heartbeat the drives are told to watch (0x1016:1 in each node's sdo), and for how long
            "heartbeat_producer": round(m.heartbeat_period_s * 1000),
            "heartbeat_multiplier": m.heartbeat_multiplier,
        },
        "nodes": {},
    }
    written = []
    for axis, n in config.nodes.items():
        dcf = out / f"{axis}.dcf"
        write_dcf(n.od, dcf, n.node_id, m.nominal_bitrate, {})  # the device: no ParameterValue
        written.append(dcf)
        doc["nodes"][axis] = _node(n, dcf.name, m, {k: n.source[k] for k in OWN_KEYS if k in n.source})
    bus = out / "bus.yml"
    with open(bus, "w", encoding="utf-8") as f:
        f.write("# Written by drive-bridge export ros2 from " + str(config.path) + "\n")
        yaml.dump(doc, f, Dumper=_Dumper, sort_keys=False, default_flow_style=None)
    return [bus] + written


def _node(n: NodeConfig, dcf_name: str, master: MasterConfig, own: dict) -> dict:
    if n.units_from_drive:
        raise UserError(
            f"nodes.{n.axis}.scaling takes the units from the drive: ros2_canopen needs them in "
            f"scale_pos_to_dev; give increments_per_rev (and velocity_unit, rated_torque_Nm) as "
            f"bringup.json's units for the axis say, then export"
        )
    period_s = master.sync_period_s
    feed = n.scaling.feed_m_per_rev  # a linear axis: device units per m
    inc_per_unit = n.scaling.inc_per_rad if feed is None else n.scaling.increments_per_rev / feed
    mode = 8 if any((TARGET_POSITION, 0) in p.mapping for p in n.rpdo) else 7
    entry = {
        "node_id": n.node_id,
        "dcf": dcf_name,
        "driver": "ros2_canopen::Cia402Driver",
        "package": "canopen_402_driver",
        "period": max(1, round(period_s * 1000)),
        "position_mode": mode,
        "scale_pos_to_dev": float(inc_per_unit),
        "scale_pos_from_dev": float(1 / inc_per_unit),
        "heartbeat_producer": n.heartbeat_producer_ms,
        "rpdo": _pdos(n, n.rpdo, RPDO_COMMUNICATION),
        "tpdo": _pdos(n, n.tpdo, TPDO_COMMUNICATION),
        "sdo": _sdo(n, period_s, master),
    }
    entry.update(own)
    return entry


def _pdos(n: NodeConfig, pdos: tuple[PdoConfig, ...], comm: int) -> dict:
    by_num = {p.number: p for p in pdos}
    out: dict[int, dict[str, Any]] = {}
    for num in range(1, 5):
        if comm + num - 1 not in n.od:
            continue
        p = by_num.get(num)
        if p is None:
            out[num] = {"enabled": False}
            continue
        out[num] = {
            "enabled": True,
            "cob_id": Hex(p.cob_id) if p.cob_id else "auto",
            "transmission": p.transmission,
            "mapping": [{"index": Hex(i), "sub_index": s} for i, s in p.mapping],
        }
        if p.event_timer_ms is not None:
            out[num]["event_timer"] = p.event_timer_ms
        if comm == TPDO_COMMUNICATION:  # as bring-up writes it (0: never the EDS default)
            out[num]["inhibit_time"] = p.inhibit_time_100us
    return out


def _sdo(n: NodeConfig, period_s: float, master: MasterConfig) -> list[dict]:
    """What drive-bridge's bring-up writes besides PDOs (:func:`~drive_bridge.master.bringup.settings`),
    as ros2_canopen's ``sdo``; the heartbeat is the node's ``heartbeat_producer`` and the
    communication cycle the master's ``sync_period``."""
    return [
        {"index": Hex(i), "sub_index": s, "value": v}
        for i, s, v in settings(n.axis, n, period_s, master)
        if i not in (HEARTBEAT_PRODUCER, CYCLE_PERIOD) and n.od.get_variable(i, s) is not None
    ]
