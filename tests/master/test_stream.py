"""Streaming's fault paths: every axis quick-stopped, the data so far kept."""

from __future__ import annotations

import numpy as np
import yaml

from drive_bridge.recorder import record
from harness.support import Bench, clean_config, quick_config, read_csv


def run_record(tmp_path, sim_cfg, config=None, axes=None, on_progress=None):
    config = config or quick_config()
    if axes:
        config = config.only(axes)
    bench = Bench(sim_cfg)
    hook = (lambda plan: lambda k: on_progress(bench, k)) if on_progress else None
    return bench, record(config, bench.link, tmp_path, on_plan=hook)


# ---------------------------------------------------------------- fault paths
def assert_stopped_and_kept(bench, tmp_path, result, axis, reason):
    assert not result.ok and result.aborted.axis == axis and reason in result.aborted.reason
    meta = yaml.safe_load((tmp_path / "meta.yaml").read_text())
    assert meta["status"] == "aborted" and meta["abort"]["axis"] == axis
    names, data = read_csv(tmp_path / "log.csv")
    assert 0 < len(data) < meta["counts"]["cycles_planned"]
    assert len(data) == meta["counts"]["cycles_sent"]
    bench.link.clock.sleep(0.01)  # the holding brakes engage
    for name, drive in bench.robot.drives.items():  # every axis stands still and is held:
        assert abs(drive.plant_state[1]) < 0.05  # on its brake (switch on disabled) or
        held = 1 if name in ("x", "y") else 5  # powered (quick stop active), or faulted
        assert drive.state in (held, 7), (name, drive.state)


def test_following_error_fault_stops_every_axis(tmp_path):
    # a hidden 5 Nm load on Y is more than the drive's 3.8 Nm: it cannot follow
    sim = clean_config(effects={"y": {"load": {"LOAD": 5.0}}})
    bench, result = run_record(tmp_path, sim, quick_config(together=True))
    assert_stopped_and_kept(bench, tmp_path, result, "y", "following error (EMCY 0x8611)")


def test_heartbeat_loss_stops_every_axis(tmp_path):
    def silence_z(bench, k):
        if k == 500:
            bench.robot.drives["z"].objects.set(0x1017, 0, 0)  # producer off

    bench, result = run_record(tmp_path, clean_config(), quick_config(together=True), on_progress=silence_z)
    assert_stopped_and_kept(bench, tmp_path, result, "z", "heartbeat lost")


def test_missing_tpdos_stop_every_axis(tmp_path):
    def unplug_x(bench, k):
        if k == 400:
            bench.robot.drives["x"].online = False

    bench, result = run_record(tmp_path, clean_config(), quick_config(together=True), on_progress=unplug_x)
    assert not result.ok and result.aborted.axis == "x" and "no TPDO" in result.aborted.reason
    assert "the limit is 20 ms" in result.aborted.reason
    assert "axis x: quick stop not confirmed" in result.aborted.reason  # it is gone from the bus
    names, data = read_csv(tmp_path / "log.csv")
    assert np.isnan(data[-1, names.index("x_position_rad")]) and data[-1, names.index("x_valid")] == 0
    # every SYNC after the unplug is a counted gap, up to the first past the 20 ms the drive waits for
    # setpoints itself (the project's drive profile: 10 periods)
    gaps = np.flatnonzero(data[:, names.index("x_valid")] == 0)
    assert result.missing["x"] == len(gaps) and np.all(np.diff(gaps) == 1) and gaps[-1] == len(data) - 1
    silent = (gaps[-1] - (gaps[0] - 1)) * 0.002  # from the last complete row's SYNC
    assert 0.020 < silent <= 0.020 + 2 * 0.002 + 1e-9
    assert result.missing["y"] == result.missing["z"] == 0


def test_ctrl_c_stops_every_axis(tmp_path):
    def interrupt(bench, k):
        if k == 300:
            raise KeyboardInterrupt

    bench, result = run_record(tmp_path, clean_config(), quick_config(together=True), on_progress=interrupt)
    assert not result.ok and "Ctrl-C" in result.aborted.reason
    assert (tmp_path / "log.csv").exists()


def test_a_second_quick_stop_in_one_process_waits_until_the_axes_stand(tmp_path):
    """The first quick stop leaves statusword bit 10 set in QUICK STOP ACTIVE; the second must
    read the drive afresh and wait for standstill, not trust a bit of the earlier stop."""
    from drive_bridge.sim import kernel

    bench = Bench(clean_config())
    config = quick_config(together=True)

    def interrupt(k):
        if k >= 300:
            raise KeyboardInterrupt

    for run in range(2):
        result = record(config, bench.link, tmp_path / str(run), on_plan=lambda plan: interrupt)
        assert "Ctrl-C" in result.aborted.reason
        for drive in bench.robot.drives.values():  # at the moment the stop returned
            assert abs(drive.plant_state[kernel.V]) < 0.06, (
                run,
                drive.axis.name,
                drive.plant_state[kernel.V],
            )


def test_a_can_error_frame_stops_every_axis(tmp_path):
    """An error frame the interface reports (bus errors, error passive, bus-off) stops the motion
    as a lost drive does."""
    import can

    def disturb(bench, k):
        if k == 500:
            bench.link.bus_errors.on_message_received(can.Message(is_error_frame=True))

    bench, result = run_record(tmp_path, clean_config(), quick_config(together=True), on_progress=disturb)
    assert not result.ok and "error frame" in result.aborted.reason
    names, data = read_csv(tmp_path / "log.csv")
    assert 500 <= len(data) < 700
