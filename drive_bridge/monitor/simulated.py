"""A simulated week of production with the monitor listening beside it.

The simulated robot (in lockstep: simulated time waits for the code) is brought up and homed
by drive-bridge's master and then runs ``shifts`` shifts of pick-and-place
(:mod:`drive_bridge.production`), each ``shift_s`` seconds of motion; between shifts the hall
is off -- the drives hold, nothing is simulated -- and the frames the monitor sees are stamped
at the shift's hour of the week (three shifts a day, from the link's epoch).  A ``wear`` effect in
the simulator's YAML raises an axis's friction with the distance it travels, shift by shift.
The monitor gets every frame on the bus as a listener would, through the link's trace tap,
and sends none: it has no bus to send on.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import cast

import can

from ..config import BusConfig
from ..connect import open_link
from ..errors import MotionAborted
from ..master.bringup import bring_up
from ..master.homing import home
from ..master.link import TraceRecorder
from ..production import run_shift
from ..sim.kernel import DISTANCE
from .watch import Monitor

WEEK_S = 7 * 24 * 3600.0
SHIFTS = 21  # three a day
SHIFT_S = 60.0  # motion simulated per shift [s]


class Tap(can.Listener):
    """Every frame on the simulated bus, handed to the monitor stamped at its hour of the week.

    Parameters
    ----------
    monitor : Monitor
        The monitor.
    """

    def __init__(self, monitor: Monitor):
        self.monitor = monitor
        self.offset = 0.0  # added to the simulation's clock [s]
        self.last = 0.0

    def on_message_received(self, msg: can.Message) -> None:
        self.last = msg.timestamp + self.offset
        self.monitor.frame(msg.arbitration_id, msg.data, self.last)

    def stop(self) -> None:
        """(A trace's interface: nothing to close.)"""


@dataclass
class Week:
    """The shifts run, how the last ended, and each axis's travel [rad, motor side] (the
    distance its wear grows with).

    Parameters
    ----------
    shifts : int
        The shifts run.
    aborted : MotionAborted or None
        How the last ended, where it was stopped.
    travel_rad : dict of str to float
        Per axis, its travel [rad, motor side].
    """

    shifts: int
    aborted: MotionAborted | None
    travel_rad: dict[str, float]


def simulated_week(
    config: BusConfig,
    monitor: Monitor,
    say: Callable[[str], None],
    *,
    sim_config: str | None = None,
    shifts: int = SHIFTS,
    shift_s: float = SHIFT_S,
    seed: int = 0,
) -> Week:
    """Run ``shifts`` shifts of ``shift_s`` seconds of production on the simulated robot
    ``sim_config`` with ``monitor`` listening; the last window of every axis closed at the end.

    Parameters
    ----------
    config : BusConfig
        The bus configuration.
    monitor : Monitor
        The monitor.
    say : callable
        Where lines for the user go.
    sim_config : str, optional
        The simulated robot (a YAML, or a shipped one's name).
    shifts : int
        How many shifts.
    shift_s : float
        Each shift's production [s].
    seed : int
        Seed of the production.

    Returns
    -------
    Week
        The shifts run, how the last ended, each axis's travel.
    """
    tap = Tap(monitor)
    # the lockstep link hands a trace every frame on the bus as it is seen: the tap takes a trace's place
    as_trace = cast(TraceRecorder, tap)
    with open_link(config, sim=True, sim_config=sim_config) as link:
        robot = link.robot  # type: ignore[attr-defined]
        link.add_trace(as_trace)
        try:
            axes = bring_up(link, config)
            home(link, axes, config)
            done, aborted = 0, None
            while done < shifts and aborted is None:
                tap.offset = link.epoch + done * WEEK_S / shifts - robot.time
                say(f"shift {done + 1} of {shifts}: {shift_s:g} s of pick-and-place")
                aborted = run_shift(link, config, axes, shift_s, seed + done).aborted
                done += 1
                monitor.tick(tap.last + 1.0)  # the hall goes quiet: the samples so far are handed on
            travel = robot.plant.state[:, DISTANCE]
            travel_rad = {name: float(travel[i]) for i, name in enumerate(robot.config.axes)}
        finally:
            link.remove_trace(as_trace)
    if aborted is None:  # the week is over: every window closes
        monitor.tick(tap.last + monitor.settings.max_span_s)
    return Week(done, aborted, travel_rad)
