"""The monitor on a bus: it decodes a production it did not plan and never sends a frame (a third
listener on the bus sees exactly what the production put there); an adapter that is missing at
start or fails while listening is reopened; error frames are counted, not fatal."""

from __future__ import annotations

import signal
import subprocess
import sys
import threading
import uuid

import can
import pytest

from drive_bridge.config import load_bus_config
from drive_bridge.connect import open_link
from drive_bridge.master.bringup import bring_up
from drive_bridge.master.homing import home
from drive_bridge.monitor import Monitor, Settings, listen, live
from drive_bridge.monitor.live import ListenOnly
from drive_bridge.production import run_shift
from drive_bridge.resources import DEFAULT_BUS_CONFIG

SHIFT_S = 30.0


@pytest.fixture(scope="module")
def production() -> list[can.Message]:
    """Every frame of a homed simulated robot's shift of pick-and-place (lockstep), stamped as a
    capture of it would be."""
    config = load_bus_config(DEFAULT_BUS_CONFIG)
    frames: list[can.Message] = []

    class Keep(can.Listener):
        def on_message_received(self, msg: can.Message) -> None:
            frames.append(
                can.Message(
                    arbitration_id=msg.arbitration_id,
                    data=bytes(msg.data),
                    is_extended_id=msg.is_extended_id,
                    is_remote_frame=msg.is_remote_frame,
                    timestamp=msg.timestamp + epoch,
                )
            )

        def stop(self) -> None:
            pass

    with open_link(config, sim=True) as link:
        epoch = link.epoch
        axes = bring_up(link, config)
        home(link, axes, config)
        link.add_trace(Keep())
        assert run_shift(link, config, axes, SHIFT_S, seed=3).aborted is None
    return frames


class FailsOnRecv(can.BusABC):
    """An adapter unplugged while it was read."""

    def __init__(self, bus: can.BusABC):
        self._bus = bus
        super().__init__(channel=None)

    def _recv_internal(self, timeout):
        raise can.CanOperationError("device disconnected")

    def send(self, msg, timeout=None):
        raise AssertionError("not sent on")

    def shutdown(self) -> None:
        super().shutdown()
        self._bus.shutdown()


@pytest.mark.slow  # a shift of production in lockstep, replayed frame by frame
def test_the_monitor_identifies_a_production_on_the_bus_and_sends_nothing(production, tmp_path, monkeypatch):
    monkeypatch.setattr(live, "RETRY_S", 0.05)
    channel = f"monitor-{uuid.uuid4().hex}"

    def virtual() -> can.BusABC:
        return can.Bus(interface="virtual", channel=channel, preserve_timestamps=True)

    opened = []
    good = threading.Event()

    def opener() -> can.BusABC:  # missing at first, then lost once, then there
        opened.append(len(opened))
        if len(opened) == 1:
            raise can.CanInitializationError("no such adapter")
        if len(opened) == 2:
            return FailsOnRecv(virtual())
        bus = virtual()
        good.set()
        return bus

    config = load_bus_config(DEFAULT_BUS_CONFIG)
    events: list = []
    said: list[str] = []
    m = Monitor(
        config, tmp_path / "monitor", Settings(window_s=15.0, history=False), events.append, background=True
    )
    sender, third = virtual(), virtual()  # the production's frames, and a capture beside them
    result = {}
    thread = threading.Thread(
        target=lambda: result.update(seen=listen(m, config, said.append, once=True, opener=opener))
    )
    thread.start()
    assert good.wait(10)
    for i, msg in enumerate(production):
        sender.send(msg)
        if i in (1000, 2000, 3000):
            sender.send(can.Message(is_error_frame=True, timestamp=msg.timestamp, arbitration_id=0x20000004))
    thread.join(120)
    assert not thread.is_alive()
    captured = []
    while (msg := third.recv(0.1)) is not None:
        captured.append(msg)
    sender.shutdown()
    third.shutdown()
    seen = result["seen"]
    assert len(captured) == len(production) + 3  # the production's frames and the error frames: no more
    assert seen.error_frames == 3 and seen.reconnections == 2
    assert any("cannot open (no such adapter)" in s for s in said)
    assert any("lost (device disconnected)" in s for s in said)
    windows = {e["axis"]: e for e in events if e["event"] == "window"}
    assert set(windows) == {"x", "y", "z"}
    for axis, w in windows.items():
        assert w["determined"], (axis, w["why"])


def test_a_listen_only_bus_refuses_to_send():
    bus = ListenOnly(can.Bus(interface="virtual", channel=f"monitor-{uuid.uuid4().hex}"))
    with pytest.raises(can.CanOperationError, match="never sends"):
        bus.send(can.Message(arbitration_id=0x80))
    bus.shutdown()


def test_sigterm_ends_the_monitor_cleanly_and_keeps_its_state(tmp_path):
    command = [sys.executable, "-m", "drive_bridge", "monitor", "-i", "virtual", "-c", uuid.uuid4().hex]
    command += ["--dir", str(tmp_path / "monitor"), "--no-history"]
    proc = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    lines = []
    for line in proc.stdout:  # type: ignore[union-attr]
        lines.append(line)
        if line.startswith("listening on"):
            break
    proc.send_signal(signal.SIGTERM)
    out, err = proc.communicate(timeout=30)
    assert proc.returncode == 0, err
    assert "stopped (SIGTERM): 0 frames" in out and "kept in" in out
    assert (tmp_path / "monitor" / "state.json").is_file()
    assert "Traceback" not in err


def test_a_monitor_listens_without_the_simulator_or_the_identification_loaded():
    """On a real bus the monitor's process loads neither the simulator (numba and its compiled
    kernels) nor the identification (scipy's signal processing): a window is identified in a worker
    process of its own, which loads them; ``monitor`` listened after 1.8-2.2 s of start where it
    loaded them, 0.55 s without (2026-11-29)."""
    code = (
        "import sys; import drive_bridge.cli.monitor; "
        "from drive_bridge.monitor import Monitor, Settings, listen; "
        "heavy = ('numba', 'scipy.signal', 'drive_bridge.sim.kernel', 'drive_bridge.ident.identify'); "
        "print(sorted(m for m in heavy if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"
    from drive_bridge import monitor

    assert callable(monitor.simulated_week)  # the simulated week, loaded when asked for
