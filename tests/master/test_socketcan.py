"""What only a kernel CAN stack has, in the project's SocketCAN guest (tools/vcan_guest.sh: Debian's
kernel with vcan, can-raw and can-bcm under qemu, this machine's userland read-only): SYNC from the
kernel's broadcast manager, error frames, and ``drive-bridge sim`` and ``record`` over socketcan with a
candump of the stream.  The guest runs under software emulation: these test function, not timing
(a 20 ms SYNC there).  Run with DRIVE_BRIDGE_GUEST=1 (.ci/run does, on their own: the emulation takes
both cores for minutes and would upset the timing of the tests beside it); skipped, with the reason,
otherwise and where the guest cannot boot."""

from __future__ import annotations

import os
import shutil
import subprocess
import textwrap
from pathlib import Path

import numpy as np
import pytest
import yaml

from drive_bridge.resources import DEFAULT_BUS_CONFIG, PROJECT_EDS
from harness.paths import ROOT

pytestmark = [pytest.mark.slow, pytest.mark.realtime, pytest.mark.third_party]

GUEST = ROOT / "tools" / "vcan_guest.sh"
WORK = Path(os.environ.get("VCAN_WORK", "/tmp/vcan"))
PYTHON = Path(os.sys.executable)


def _why_not() -> str | None:
    if not os.environ.get("DRIVE_BRIDGE_GUEST"):
        return (
            "the SocketCAN guest's emulation takes both cores for minutes: set DRIVE_BRIDGE_GUEST=1 to run "
            "these tests in it (.ci/run does, after tools/vcan_guest.sh setup)"
        )
    if shutil.which("qemu-system-x86_64") is None or shutil.which("candump") is None:
        return "no qemu-system-x86_64 or can-utils: run tools/vcan_guest.sh setup (as root) for the SocketCAN guest"
    if not list((WORK / "kernel" / "boot").glob("vmlinu*-*")) or not (WORK / "initramfs.cpio.gz").exists():
        return f"the SocketCAN guest is not set up under {WORK}: run tools/vcan_guest.sh setup (as root)"
    if os.geteuid() != 0:
        return "the SocketCAN guest runs as root"
    return None


def _in_guest(tmp_path: Path, script: str, timeout: float = 600) -> subprocess.CompletedProcess:
    """Run ``script`` (bash) in a freshly booted guest; its files go to ``tmp_path/guest`` (the one
    folder the guest writes to the host)."""
    why = _why_not()
    if why:
        pytest.skip(why)
    share = tmp_path / "guest"
    share.mkdir(exist_ok=True)
    path = share / "script.sh"
    path.write_text(
        "set -u\nexport NUMBA_CPU_NAME=generic PYTHONDONTWRITEBYTECODE=1\n" + textwrap.dedent(script)
    )
    env = {**os.environ, "VCAN_OUT": str(share), "VCAN_WORK": str(WORK), "VCAN_TIMEOUT": str(int(timeout))}
    return subprocess.run(
        ["bash", str(GUEST), "run-file", str(path)],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=timeout + 60,
    )


def test_sync_from_the_broadcast_manager_and_error_frames(tmp_path):
    """The engine's port takes SYNC from the kernel's broadcast manager (python-can's periodic send on
    socketcan: one job of 240 frames carrying the counter 1..240), sees each SYNC with its kernel stamp
    and its count, in order, records it as the master's own frame, and passes an error frame on to
    the engine."""
    probe = tmp_path / "guest" / "probe.py"
    probe.parent.mkdir(exist_ok=True)
    probe.write_text(
        textwrap.dedent("""
        import json, sys, can, numpy as np
        from drive_bridge.cia.buses import open_bus
        from drive_bridge.master.port import BusPort, TraceRing
        port = BusPort(open_bus("socketcan", "vcan0"), TraceRing(4096, np.zeros))
        stamps, counts, errors = [], [], []
        port.receive({0x80: lambda data, t: (stamps.append(t), counts.append(data[0]))}, lambda: errors.append(1))
        port.start_sync(0.01, 240)
        end = port.now() + 1.0
        while port.now() < end:
            port.wait_sync(end)
        can.Bus(interface="socketcan", channel="vcan0").send(
            can.Message(arbitration_id=0x4, is_error_frame=True, dlc=8, data=bytes(8), is_extended_id=False))
        end = port.now() + 0.1
        while port.now() < end:
            port.wait_sync(end)
        port.stop_sync()
        frames = port.ring.take()
        json.dump({"periodic": port.periodic_sync, "source": port.sync_source, "syncs": len(stamps), "counts": counts,
                   "period_ms": float(np.median(np.diff(stamps)) * 1e3), "errors": len(errors),
                   "own_syncs": sum(1 for m in frames if m.arbitration_id == 0x80 and not m.is_rx),
                   "error_frames": sum(1 for m in frames if m.is_error_frame)}, open(sys.argv[1], "w"))
    """)
    )
    result = tmp_path / "guest" / "probe.json"
    run = _in_guest(tmp_path, f"cd {ROOT} && {PYTHON} {probe} {result}\n", timeout=300)
    assert run.returncode == 0, run.stdout[-2000:]
    import json

    got = json.loads(result.read_text())
    assert got["periodic"] and "broadcast manager" in got["source"]
    assert got["syncs"] >= 80 and 9.5 < got["period_ms"] < 12.0  # BCM re-arms after each frame
    assert got["own_syncs"] == got["syncs"]  # in the trace as the master's frames, not received ones
    counts = got["counts"]
    assert counts[0] == 1 and all(b == a % 240 + 1 for a, b in zip(counts, counts[1:]))  # in order, none lost
    assert got["errors"] == 1 and got["error_frames"] == 1


#: a run in which the emulated kernel's own SYNC came more than this many periods late runs again,
#: up to :data:`KERNEL_LATE_RUNS` times: the drives' clocks took records meanwhile, as a drive's does
#: without SYNC (CI's guest under TCG: one SYNC in some 120 held up 71 ms, at a 20 ms period;
#: a real kernel's broadcast manager is late by microseconds)
KERNEL_LATE_PERIODS = 1.5
KERNEL_LATE_RUNS = 3


def _candump(share: Path) -> list[tuple[float, str]]:
    """The run's candump as (stamp [s], COB-ID in hex) per frame, in order (none where it left none)."""
    dump = share / "candump.log"
    frames = []
    for line in dump.read_text().splitlines() if dump.exists() else []:
        stamp, _channel, frame = line.split()[:3]
        frames.append((float(stamp.strip("()")), frame.split("#")[0]))
    return frames


def _longest_sync_gap(share: Path) -> float:
    """The longest time between two SYNCs in the run's candump [s]."""
    stamps = [stamp for stamp, cob_id in _candump(share) if cob_id == "080"]
    return float(np.max(np.diff(stamps))) if len(stamps) > 1 else 0.0


def _drive_late(share: Path, cob_id: str) -> int:
    """The SYNCs in the run's candump followed by the next SYNC before the frame ``cob_id`` answered
    them."""
    late, answered = 0, True
    for _stamp, frame in _candump(share):
        if frame == "080":
            late += not answered
            answered = False
        elif frame == cob_id:
            answered = True
    return late


def _said(share: Path) -> str:
    """What a failed run left: the record's errors, the simulated drives' output and, from the
    candump, the longest gap between the SYNCs and between the heartbeats of each node."""
    stamps: dict[str, list[float]] = {}
    for stamp, cob_id in _candump(share):
        if cob_id == "080" or cob_id.startswith("7"):
            stamps.setdefault(cob_id, []).append(stamp)
    gaps = [
        f"{cob_id}: {len(times)} frames, longest gap {np.diff(times).max(initial=0.0) * 1e3:.0f} ms"
        for cob_id, times in sorted(stamps.items())
    ]
    sim = share / "sim.log"
    return "\n".join(
        [(share / "record.err").read_text()[-3000:], "sim:", sim.read_text()[-1500:] if sim.exists() else ""]
        + gaps
    )


def test_sim_and_record_over_socketcan_with_a_candump_of_the_stream(tmp_path):
    """``drive-bridge sim`` and ``record`` as two processes on vcan0: bring-up, a quick campaign on y,
    the one axis bus.yml names, with SYNC from the kernel's broadcast manager at 20 ms
    (``master.sync_producer: interface``), each carrying its count, the engine in its own process, the master's processes stopped 200 ms
    at a time, every second on average (``harness/stalls.py``); candump sees every count in order and
    the stream the trace holds, and no row is missing."""
    doc = yaml.safe_load(DEFAULT_BUS_CONFIG.read_text())
    doc["master"].update(
        interface="socketcan",
        channel="vcan0",
        sync_period=20000,
        # how long the drives wait for the master's heartbeat (the kernel's broadcast manager, 100 ms):
        # 50 periods, as emulated a vCPU can be held up for more than the 3 of a real machine (CI saw
        # 584 ms between two, the SYNCs of the other vCPU on time); and how long the master waits for theirs
        heartbeat_multiplier=50,
        heartbeat_consumer_ms=2000,
        sync_producer="interface",
        sdo_timeout_s=2.0,
        state_timeout_s=5.0,
    )
    doc["defaults"]["dcf"] = str(PROJECT_EDS)
    # the bus as bus.yml names it: y alone, so the run brings up every node it names and each SYNC
    # carries its count (x and z, simulated beside it but not named, are not told the counter: they
    # answer counted SYNCs with EMCY 0x8240, which this master does not listen to)
    doc["nodes"] = {"y": doc["nodes"]["y"]}
    share = tmp_path / "guest"
    share.mkdir()
    cfg = share / "bus.yml"
    cfg.write_text(yaml.safe_dump(doc, sort_keys=False))
    # numba's cache, compiled here for a CPU the emulated one can run (else LLVM runs under emulation)
    subprocess.run(
        [str(PYTHON), "-c", "import drive_bridge.sim.cyclic as c, drive_bridge.sim.robot; c.compile_all()"],
        env={**os.environ, "NUMBA_CPU_NAME": "generic"},
        check=True,
        cwd=ROOT,
    )
    db = f"{PYTHON} -m drive_bridge"
    script = f"""
        cd {ROOT}
        {db} sim -i socketcan -c vcan0 --config {cfg} > {share}/sim.log 2>&1 &
        SIM=$!
        timeout 300 candump -n 3 vcan0,700:780 > /dev/null || echo "no heartbeat from the drives"
        # (candump's socket with a receive buffer of 8 MB: with the default it once dropped a SYNC
        # the engine had, under emulation)
        candump -L -r 8388608 vcan0 > {share}/candump.log 2>&1 &
        DUMP=$!
        {db} record -i socketcan -c vcan0 --config {cfg} --quick --axes y --yes --out {share}/rec \\
            > {share}/record.out 2> {share}/record.err &
        REC=$!
        {PYTHON} -m harness.stalls --master $REC --length 0.2 --every 1.0 --seed 1 --log {share}/stalls.jsonl &
        wait $REC
        echo $? > {share}/record.rc
        sleep 0.5; kill $DUMP; kill -INT $SIM; wait $SIM
        true
    """
    for _ in range(KERNEL_LATE_RUNS):
        shutil.rmtree(share / "rec", ignore_errors=True)  # (what an earlier run left)
        for made in ("candump.log", "stalls.jsonl", "record.rc", "record.err", "record.out", "sim.log"):
            (share / made).unlink(missing_ok=True)
        run = _in_guest(tmp_path, script, timeout=900)
        assert run.returncode == 0, run.stdout[-3000:]
        rc = int((share / "record.rc").read_text())
        if (
            rc in (0, 5)
            or _longest_sync_gap(share) <= KERNEL_LATE_PERIODS * doc["master"]["sync_period"] / 1e6
        ):
            break  # (a run the emulated kernel's own SYNC was not late in is judged as it is)
    assert rc in (0, 5), _said(share)  # done (5: the emulated machine's timing said)
    meta = yaml.safe_load((share / "rec" / "meta.yaml").read_text())
    engine = meta["timing"]["engine"]
    assert meta["status"] == "ok" and "broadcast manager" in engine["sync_source"]
    assert "a process of its own" in engine["host"]
    dump = (share / "candump.log").read_text().splitlines()
    syncs = [line for line in dump if " vcan0 080#" in line]
    assert len(syncs) >= meta["counts"]["cycles_sent"]  # every row's SYNC on the bus
    counts = [int(line.split("#")[1], 16) for line in syncs]
    assert all(b == a % 240 + 1 for a, b in zip(counts, counts[1:]))  # each with its count, in order
    # every row has its sample, but where the emulated drive itself answered a SYNC only after the
    # next one was on the bus (its process held up under TCG: a real drive's synchronous TPDO is
    # within the SYNC's window) -- a TPDO belongs to the SYNC before it in bus order
    assert meta["timing"]["samples_missing"]["y"] <= _drive_late(share, "182"), _said(share)
    assert engine["syncs_lost"] == 0
    assert (share / "stalls.jsonl").exists()  # (the master was stopped meanwhile)
    assert any(" vcan0 202#" in line for line in dump) and any(" vcan0 182#" in line for line in dump)
