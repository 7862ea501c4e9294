"""The Link contract: one scenario, run over the lockstep link and over the wall-clock link to the
simulated drives in their own process (python-can's udp_multicast bus, canopen's Notifier)."""

from __future__ import annotations

import can
import numpy as np
import pytest

from drive_bridge.config import load_bus_config
from drive_bridge.connect import open_link
from drive_bridge.master.bringup import bring_up, scan
from drive_bridge.master.campaign import trapezoid
from drive_bridge.master.hold import quick_stop
from drive_bridge.master.link import Link, MasterNetwork, TraceRecorder
from drive_bridge.tuning import motion
from drive_bridge.tuning.motion import Motion
from harness.machine_floor import beside_the_floor, run_stall_ms
from harness.support import BUS_CONFIG

pytestmark = [pytest.mark.slow, pytest.mark.realtime]


@pytest.mark.parametrize("realtime", [False, True], ids=["lockstep", "process"])
def test_one_scenario_over_every_link(realtime, tmp_path):
    config = load_bus_config(BUS_CONFIG).only(["y"])
    lim = config.nodes["y"].limits

    def scenario() -> tuple[Motion, float, float]:
        with open_link(config, sim=True, realtime=realtime) as link:
            assert isinstance(link, Link)
            assert isinstance(link.network, MasterNetwork) and link.threaded is realtime
            for name in ("now", "sleep", "wait_until"):
                assert callable(getattr(link.clock, name))
            found = scan(link, config)
            assert sorted(found.found) == [2] and found.unexpected == [1, 3] and not found.missing
            axes = bring_up(link, config)
            trace = TraceRecorder(tmp_path / "trace.blf", background=link.threaded)
            link.add_trace(trace)
            t0 = link.clock.now()
            here = float(config.nodes["y"].scaling.position_from_device(axes["y"].node.sdo[0x6064].raw))
            demand = trapezoid(here, here + 2.0, 0.3 * lim.max_velocity, 0.3 * lim.max_acceleration, 0.002)
            m = motion.run(config, link, axes, {"y": np.concatenate([demand, np.full(100, demand[-1])])})
            elapsed = link.clock.now() - t0 - len(demand) * 0.002
            link.remove_trace(trace)
            trace.stop()
            assert quick_stop(link, axes, 1.0) == []
        return m, here, elapsed

    # on the wall clock, a run the machine stalled (its own floor held up as long) is run again
    m, here, elapsed = (
        beside_the_floor(scenario, lambda run: run_stall_ms(run[0])) if realtime else scenario()
    )
    assert m.aborted is None
    # on the wall clock a period the master was late in has no SYNC and no sample: counted, and the rest
    skipped = m.timing.engine.get("periods_skipped", 0)
    assert np.count_nonzero(np.isnan(m.position["y"])) <= 0.01 * len(m.position["y"]) + skipped
    arrived = m.position["y"][np.isfinite(m.position["y"])][-1]
    assert abs(arrived - (here + 2.0)) < 0.01  # it arrived
    if not skipped:  # on time it does not overshoot (a period a late master skipped, a drive in CSP
        # goes on at its last velocity: it may overshoot then, and come back)
        assert np.nanmax(m.position["y"]) - (here + 2.0) < 0.01
    assert elapsed >= 0  # the link's clock moved
    with can.LogReader(str(tmp_path / "trace.blf")) as reader:
        frames = list(reader)
    ids = {f.arbitration_id for f in frames}
    assert {0x080, 0x202, 0x182, 0x282} <= ids  # SYNC, RPDO1, TPDO1, TPDO2 of node 2
    stamps = np.array([f.timestamp for f in frames if f.arbitration_id == 0x080])
    assert np.all(np.diff(stamps) > 0)  # SYNCs in time order
