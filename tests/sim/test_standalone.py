"""``drive-bridge sim``: the simulated drives as a process of their own on udp_multicast, and a
master killed with SIGKILL mid-campaign: every drive stops through its own heartbeat consumer."""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import time

import canopen
import pytest
import yaml

from drive_bridge.cia.multicast import UDP_GROUP, LoopbackMulticastBus
from drive_bridge.cia.p402 import state_name
from harness.machine_floor import beside_the_floor, meta_stall_ms
from harness.support import bus_yml_beside, start_sim, wait_for

pytestmark = [pytest.mark.slow, pytest.mark.realtime]


def _x_velocity(monitor: canopen.Network) -> list[int]:
    """X's velocity actual as its TPDO 2 carries it, listened to (the newest last): an SDO request
    from here would share node 1's one SDO channel with the master's own requests while it runs."""
    velocity = [0]
    monitor.subscribe(
        0x281, lambda cob, data, ts: velocity.append(int.from_bytes(data[:4], "little", signed=True))
    )
    return velocity


def _end(drives: subprocess.Popen, monitor: canopen.Network | None) -> None:
    """The listener disconnected, the simulated drives stopped with Ctrl-C (killed after 10 s)."""
    if monitor is not None:
        monitor.disconnect()
    drives.send_signal(signal.SIGINT)
    try:
        drives.wait(timeout=10)
    except subprocess.TimeoutExpired:
        drives.kill()


def _record(cfg, out, axes: str, *options: str, **popen) -> subprocess.Popen:
    """``drive-bridge record --yes`` of ``axes`` in a process of its own, its stderr piped."""
    return subprocess.Popen(
        [sys.executable, "-m", "drive_bridge", "record", "--config", str(cfg), "--axes", axes, *options]
        + ["--yes", "--out", str(out)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
        **popen,
    )


def test_a_master_killed_mid_campaign_leaves_every_drive_stopped_by_its_heartbeat_consumer(tmp_path):
    drives, cfg, port = start_sim(tmp_path)
    monitor = None
    try:
        monitor = canopen.Network(LoopbackMulticastBus(UDP_GROUP, port))
        monitor.connect()
        emcy = []
        for node_id in (1, 2, 3):
            monitor.subscribe(
                0x80 + node_id,
                lambda cob, data, ts: emcy.append((cob & 0x7F, data[0] | data[1] << 8, time.time())),
            )
        velocity = _x_velocity(monitor)
        master = _record(cfg, tmp_path / "run", "x", start_new_session=True)
        wait_for(master.stderr, "campaign:", 120)
        node = monitor.add_node(1, None)  # SDO only: no object dictionary needed
        # X on its way to the campaign's start (6 s): wait until it moves (a loaded machine's master
        # got there later than the 1.5 s this waited once) ...
        patience = time.time() + 30
        while abs(velocity[-1]) <= 0.5 * 166886 and time.time() < patience and master.poll() is None:
            time.sleep(0.01)
        moving = abs(velocity[-1])
        if master.poll() is not None:  # it stopped on its own before X moved
            with contextlib.suppress(ProcessLookupError):  # what is left of its session (its stderr ends)
                os.killpg(master.pid, signal.SIGKILL)
            pytest.fail(
                f"the master ended (exit {master.returncode}) before X moved: {master.stderr.read()[-1500:]}"
            )
        os.killpg(master.pid, signal.SIGKILL)  # the master and its cyclic engine, as a power cut would
        killed = time.time()
        assert moving > 0.5 * 166886  # ... at more than 0.5 rad/s when the master dies
        master.wait()
        # the consumer time bring-up wrote: 3 heartbeat periods, or, where the master fed X's FIFO
        # ahead, the stall that covers and 2 heartbeat periods more (the FIFO runs dry first: a
        # planned stop)
        consumer_s = (int.from_bytes(node.sdo.upload(0x1016, 1), "little") & 0xFFFF) / 1000.0
        speeds = []
        while time.time() < killed + consumer_s + 1.0:
            raw = node.sdo.upload(0x606C, 0)
            speeds.append((time.time(), abs(int.from_bytes(raw, "little", signed=True))))
            time.sleep(0.01)
        lost = [t for n, code, t in emcy if n == 1 and code == 0x8130]
        assert lost and lost[0] - killed <= consumer_s + 0.1  # the consumer time (+ the wall clock's slack)
        stopped = next(t for t, v in speeds if v < 8000)  # < 0.05 rad/s in increments/s
        assert stopped - killed <= consumer_s + 0.01 + 0.15  # ... plus the quick-stop ramp
        statusword = int.from_bytes(node.sdo.upload(0x6041, 0), "little")
        assert state_name(statusword) == "QUICK STOP ACTIVE"  # stopped, and holding
    finally:
        _end(drives, monitor)


def test_on_a_terminal_the_plan_is_shown_and_yes_moves(tmp_path, capsys, monkeypatch):
    """A real bus (the simulated drives in their own process) at a terminal: the campaign's plan,
    read over a read-only bring-up, is shown before the question; 'yes' runs it."""
    from drive_bridge.cli import main
    from drive_bridge.sim.process import SimProcess
    from drive_bridge.sim.robot_config import DEFAULT_CONFIG

    drives = SimProcess(DEFAULT_CONFIG, 0.002)
    try:
        cfg = bus_yml_beside(tmp_path)
        doc = yaml.safe_load(cfg.read_text())
        doc["master"].update(interface="udp_multicast", channel=UDP_GROUP, can_options={"port": drives.port})
        cfg.write_text(yaml.safe_dump(doc))
        monkeypatch.setattr("sys.stdin.isatty", lambda: True)
        monkeypatch.setattr("builtins.input", lambda prompt: "yes")

        def recorded() -> tuple[int, dict, str]:
            code = main(
                ["record", "--config", str(cfg), "--quick", "--axes", "y", "--out", str(tmp_path / "run")]
            )
            meta = yaml.safe_load((tmp_path / "run" / "meta.yaml").read_text())
            return code, meta, capsys.readouterr().err

        # a run the machine itself stalled (its own floor held up as long) runs again
        code, meta, err = beside_the_floor(recorded, lambda run: meta_stall_ms(run[1]))
        assert code in (0, 5), meta.get("abort")  # 5: a loaded machine's timing, said
        assert err.index("units as the drive reports them") < err.index("will enable and move the real axes")
        assert (tmp_path / "run" / "log.csv").exists()
    finally:
        drives.shutdown()


def test_the_simulator_starts_without_the_tuning_tools():
    """Drives in a process of their own (``sim/process.py``, ``drive-bridge sim``'s core) import the
    simulator only: not python-control, matplotlib or the tuning code (they had cost 2.4 s of every
    start through the controller description's loop rates)."""
    code = (
        "import sys, drive_bridge.sim.robot, drive_bridge.sim.process; "
        "heavy = ('control', 'matplotlib.pyplot', 'drive_bridge.tuning.design'); "
        "print(sorted(m for m in heavy if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def test_a_sync_producer_that_drops_out_mid_campaign_ends_the_run_with_the_other_axis_held(tmp_path):
    """The drive that keeps time (x, the first that can produce SYNC) resets mid-campaign -- a power
    blip, its watchdog -- and its SYNCs stop: y, fed ahead, takes no more records and stands; the
    master ends the stream within the time its drives wait, names x and the SYNC, stops y by SDO and
    leaves it held under power; the data recorded so far is kept, no traceback."""
    drives, cfg, port = start_sim(tmp_path)
    monitor = None
    try:
        monitor = canopen.Network(LoopbackMulticastBus(UDP_GROUP, port))
        monitor.connect()
        syncs: list[float] = []
        # (each SYNC by the time its producer sent it: this listener may read them late under load)
        monitor.subscribe(0x080, lambda cob, data, ts: syncs.append(ts))
        velocity = _x_velocity(monitor)
        master = _record(cfg, tmp_path / "run", "x,y", "--quick")
        said = wait_for(master.stderr, "campaign:", 120)
        patience = time.time() + 60
        while abs(velocity[-1]) <= 0.2 * 166886 and time.time() < patience and master.poll() is None:
            time.sleep(0.005)
        assert master.poll() is None, said + master.stderr.read()
        monitor.send_message(0x000, bytes([0x81, 1]))  # NMT reset node, to x (node 1)
        reset = time.time()
        _, err = master.communicate(timeout=120)
        said += err
        assert master.returncode == 4, said
        assert "Traceback" not in said
        assert "axis x" in said and "SYNC" in said, said
        assert not [t for t in syncs if t > reset + 0.1]  # nobody else took over the SYNC
        node = monitor.add_node(2, None)
        statusword = int.from_bytes(node.sdo.upload(0x6041, 0), "little")
        assert state_name(statusword) in ("QUICK STOP ACTIVE", "OPERATION ENABLED"), state_name(statusword)
        assert (tmp_path / "run" / "log.csv").exists()
    finally:
        _end(drives, monitor)
