"""Fault injection against the simulated drives (lockstep): every fault a motion or a parameter
write can meet, and how it ended.

    python tools/fault_table.py

Motion faults (a campaign of two axes moving together): ended safely = the stop was reported,
every axis the master can reach stood still and switched off or faulted when the command
returned (one it cannot reach within 0.5 s, by its own loss-of-setpoint fault), and log.csv
holds every SYNC sent; samples lost = SYNC cycles sent whose row is missing from log.csv.  Write faults
(two drives, every phase x failure kind): ended safely = what the result says each drive holds
(RAM, stored set) is what a read-back and a power cycle show; half-written = a drive left holding
part of the new set and part of the old.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import canopen  # noqa: E402
import yaml  # noqa: E402

from drive_bridge.interrupts import Terminated  # noqa: E402
from drive_bridge.recorder import record  # noqa: E402
from drive_bridge.sim import kernel  # noqa: E402
from harness.support import Bench, clean_config, quick_config, read_csv  # noqa: E402
from harness.write_faults import CASES, NAMES, SIM, Fault, device, new_values  # noqa: E402


def motion_fault(name: str, sim, hook) -> tuple[bool, int]:
    """(ended safely, samples lost) of a two-axis campaign with ``hook(bench, k)`` in its loop."""
    bench = Bench(sim)
    with tempfile.TemporaryDirectory() as tmp:
        try:
            result = record(
                quick_config(together=True).only(["y", "z"]),
                bench.link,
                Path(tmp),
                on_plan=lambda plan: lambda k: hook(bench, k),
            )
            standing = all(
                abs(d.s[kernel.V]) < 0.06 and d.state in (1, 5, 7)
                for d in bench.robot.drives.values()
                if d.online
            )
            bench.link.clock.sleep(0.5)  # a drive the master cannot reach stops itself
            standing = standing and all(
                abs(d.s[kernel.V]) < 0.06 and d.state in (1, 5, 7) for d in bench.robot.drives.values()
            )
            meta = yaml.safe_load((Path(tmp) / "meta.yaml").read_text())
            names, data = read_csv(Path(tmp) / "log.csv")
            lost = meta["counts"]["cycles_sent"] - len(data)
            return result.aborted is not None and standing and lost == 0 and meta["status"] == "aborted", lost
        finally:
            bench.close()


def _raise(exc, at):
    def hook(bench, k):
        if k >= at:
            raise exc

    return hook


def _unplug(bench, k):
    if k >= 400:
        bench.robot.drives["z"].online = False


def _silence(bench, k):
    if k == 500:
        bench.robot.drives["z"].objects.set(0x1017, 0, 0)


MOTION = {
    "following error (EMCY 0x8611)": (
        clean_config(effects={"y": {"load": {"LOAD": 5.0}}}),
        lambda b, k: None,
    ),
    "heartbeat lost": (clean_config(), _silence),
    "feedback missing (drive off the bus)": (clean_config(), _unplug),
    "Ctrl-C": (clean_config(), _raise(KeyboardInterrupt(), 300)),
    "SIGTERM": (clean_config(), _raise(Terminated("SIGTERM"), 300)),
    "SIGHUP": (clean_config(), _raise(Terminated("SIGHUP"), 600)),
}


def write_fault(phase: str, kind: str) -> tuple[bool, int]:
    """(ended safely, drives half-written) of a two-drive transaction failing as ``kind`` in ``phase``."""
    from drive_bridge.params.write import write_all

    bench = Bench(clean_config())
    try:
        nodes = {a: bench.nodes[a] for a in ("x", "y")}
        for node in nodes.values():
            node.sdo.RESPONSE_TIMEOUT = 0.05
        before = {a: device(n) for a, n in nodes.items()}
        values = {a: new_values(a) for a in nodes}
        bench.robot.drives["y"].sdo_fault = Fault(bench.robot.drives["y"], phase, kind)
        with tempfile.TemporaryDirectory() as tmp:
            results = write_all(nodes, SIM, values, backup_dir=tmp)
        bench.robot.drives["y"].sdo_fault = None
        bench.robot.drives["y"].online = True
        now = {a: device(n) for a, n in nodes.items()}
        new = {a: device_values(a, values[a]) for a in nodes}
        half = sum(1 for a in nodes if now[a] != before[a] and now[a] != new[a])
        ok = all(r.ram != "backup" or now[a] == before[a] for a, r in results.items())
        for node in nodes.values():
            node.nmt.send_command(0x81)
        bench.link.clock.sleep(0.01)
        after = {a: device(n) for a, n in nodes.items()}
        ok = ok and all(
            r.stored_set not in ("unchanged", "backup") or after[a] == before[a] for a, r in results.items()
        )
        return ok, half
    finally:
        bench.close()


def device_values(axis, values):
    import numpy as np

    out = {}
    for n in NAMES:
        e = SIM.entries[n]
        d = e.to_device(values[n])
        out[n] = float(np.float32(d)) if e.type == "REAL32" else d
    return out


def main() -> None:
    import logging

    logging.getLogger("canopen").addHandler(logging.NullHandler())
    rows = []
    for name, (sim, hook) in MOTION.items():
        safe, lost = motion_fault(name, sim, hook)
        rows.append(("motion", name, 1, int(safe), lost, "–"))
    for phase in ("backup", "write", "verify", "store", "restore"):
        kinds = [k for p, k in CASES if p == phase]
        results = [write_fault(phase, k) for k in kinds]
        rows.append(
            (
                "write",
                f"{phase} phase: {', '.join(kinds)}",
                len(kinds),
                sum(s for s, _ in results),
                "–",
                sum(h for _, h in results),
            )
        )
    print("| kind | fault | injected | ended safely | samples lost | half-written sets |")
    print("| --- | --- | --- | --- | --- | --- |")
    for r in rows:
        print("| " + " | ".join(map(str, r)) + " |")


if __name__ == "__main__":
    canopen  # noqa: B018  (imported for its logger)
    main()
