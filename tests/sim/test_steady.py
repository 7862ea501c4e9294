"""The drives' compiled streaming SYNC (sim/steady.py) sends what the Python drive sends: a whole
recording -- bring-up, the campaign, its faults and stops -- gives the same trace and log byte for
byte with it and without it, and it runs for most of a campaign's SYNCs."""

from __future__ import annotations

import struct

import pytest

from drive_bridge.recorder import record
from drive_bridge.sim import kernel
from drive_bridge.sim.steady import SteadyStream
from harness.support import Bench, bus_yml_beside, clean_config, quick_config


def _heavy_y(bench, k):
    if k == 300:  # Y suddenly carries more than its drive can: following error
        bench.robot.plant.param[1, kernel.LOAD] = 5.0


def _silent_z(bench, k):
    if k == 500:  # Z's heartbeat stops: the master loses it
        bench.robot.drives["z"].objects.set(0x1017, 0, 0)


def _gone_x(bench, k):
    if k == 400:  # X drops off the bus mid-stream
        bench.robot.drives["x"].online = False


def _limited_x(bench, k):
    if k == 200:  # X's software limits narrowed by SDO under the stream
        limits, here = bench.nodes["x"].sdo[0x607D], bench.robot.drives["x"]._position_inc
        limits[1].raw, limits[2].raw = here - 2000, here + 2000


def _mode_of_y_changed(bench, k):
    if k == 300:  # an RPDO that puts Y into profile position (mode 1) under the stream, enabled
        bench.net.send_message(0x202, struct.pack("<Hb", 0x000F, 1))


#: the shipped bus.yml's RPDO, and as ros2_canopen's users map it: the modes of operation sent with the
#: controlword every period
SHIPPED_RPDO = """        - {index: 0x6040, sub_index: 0}   # controlword
        - {index: 0x607A, sub_index: 0}   # target position
"""
MODE_IN_RPDO = """        - {index: 0x6040, sub_index: 0}
        - {index: 0x6060, sub_index: 0}
    2:
      transmission: 1
      mapping:
        - {index: 0x607A, sub_index: 0}
"""


def recording(tmp_path, monkeypatch, compiled: bool, hook=None, config=None) -> tuple[bytes, bytes, int]:
    """trace.blf and log.csv of a short campaign with the plant's noise and a hidden load, and
    how many SYNCs the compiled path ran (``config``: the bus configuration, default the shipped
    one's)."""
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1700000000")
    ran = []
    python_drive = SteadyStream.period
    monkeypatch.setattr(
        SteadyStream,
        "period",
        lambda self: ran.append(1) is None if compiled and python_drive(self) else False,
    )
    bench = Bench(clean_config(noise=0.004, seed=3, effects={"z": {"load": {"LOAD": 0.3}}}))
    try:
        out = tmp_path / ("compiled" if compiled else "python")
        on_plan = (lambda plan: lambda k: hook(bench, k)) if hook else None
        record(config or quick_config(together=True), bench.link, out, on_plan=on_plan)
    finally:
        bench.close()
    return (out / "trace.blf").read_bytes(), (out / "log.csv").read_bytes(), len(ran)


@pytest.mark.parametrize(
    "hook",
    [None, _heavy_y, _silent_z, _gone_x, _limited_x],
    ids=["campaign", "following-error", "heartbeat-lost", "drive-gone", "software-limit"],
)
def test_the_compiled_sync_sends_what_the_python_drive_sends(tmp_path, monkeypatch, hook):
    trace, log, ran = recording(tmp_path, monkeypatch, True, hook)
    trace_py, log_py, ran_py = recording(tmp_path, monkeypatch, False, hook)
    assert ran_py == 0 and ran > 250  # it ran (the quick campaign streams ~1000 SYNCs; ~300 before the fault)
    assert log == log_py
    assert trace == trace_py


@pytest.mark.parametrize("hook", [None, _mode_of_y_changed], ids=["campaign", "mode-changed"])
def test_a_master_that_sends_the_mode_every_period_streams_on_the_compiled_path(tmp_path, monkeypatch, hook):
    """A master that maps the modes of operation (0x6060) into its RPDO, as ros2_canopen's users
    do, is streamed to on the compiled path (it once ran every SYNC in Python: a campaign took
    twice as long), with the same frames as the Python drive's -- and where the mode the RPDO
    brings is not the drive's, the Python drive takes the SYNC."""
    cfg = quick_config(bus_yml_beside(tmp_path, SHIPPED_RPDO, MODE_IN_RPDO), together=True)
    assert [r.mapping for r in cfg.nodes["y"].rpdo] == [
        ((0x6040, 0), (0x6060, 0)),
        ((0x607A, 0), (0x60B2, 0)),
    ]
    trace, log, ran = recording(tmp_path, monkeypatch, True, hook, cfg)
    trace_py, log_py, ran_py = recording(tmp_path, monkeypatch, False, hook, cfg)
    assert ran_py == 0 and ran > 250
    assert log == log_py
    assert trace == trace_py
