"""The monitor on a live bus: opened to listen only, read until told to stop, reopened when
it goes away.

The bus is opened as the master opens it (:func:`drive_bridge.cia.buses.open_bus`), switched to
the adapter's listen-only state where python-can offers one (``BusState.PASSIVE``: the controller
does not even acknowledge frames), and wrapped so that ``send`` cannot be called
(:class:`ListenOnly`): the monitor never puts a frame on the machine's bus.  A bus that fails
(adapter unplugged, interface down) is closed and reopened every :data:`RETRY_S`; error
frames and bus-off are counted and said, and listening goes on.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

import can

from ..cia.buses import open_bus
from ..config import BusConfig
from ..errors import UserError
from .watch import Monitor

log = logging.getLogger(__name__)

RETRY_S = 2.0  # a lost bus is reopened this often
RECV_S = 0.2  # the longest wait for a frame before the monitor looks at the time


class ListenOnly(can.BusABC):
    """A python-can bus that receives and refuses to send.

    Parameters
    ----------
    bus : can.BusABC
        The bus it wraps.
    """

    def __init__(self, bus: can.BusABC):
        self._bus = bus
        #: what the adapter says it is ("socketcan channel 'can0'", ...)
        self.inner_info = str(getattr(bus, "channel_info", "") or type(bus).__name__)
        self.channel_info = f"listen-only {self.inner_info}"
        self.hardware_passive = False
        try:
            bus.state = can.BusState.PASSIVE
            self.hardware_passive = True
        except (NotImplementedError, can.CanError, AttributeError, ValueError):
            pass  # the adapter has no listen-only state: the monitor still never sends
        super().__init__(channel=getattr(bus, "channel", None) or "")

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        return self._bus.recv(timeout), False

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        raise can.CanOperationError("monitor listens only: it never sends a frame")

    def shutdown(self) -> None:
        super().shutdown()
        self._bus.shutdown()


@dataclass
class Listening:
    """What a run on a bus saw.

    Parameters
    ----------
    frames : int
        Frames seen.
    error_frames : int
        Error frames seen.
    reconnections : int
        Times the bus was lost and reopened.
    stopped_by : str, optional
        The signal that ended it (Ctrl-C, SIGTERM); None where it ended otherwise.
    """

    frames: int = 0
    error_frames: int = 0
    reconnections: int = 0
    stopped_by: str | None = None


def listen(
    monitor: Monitor,
    config: BusConfig,
    say: Callable[[str], None],
    *,
    once: bool = False,
    opener: Callable[[], can.BusABC] | None = None,
    stop: threading.Event | None = None,
) -> Listening:
    """Feed ``monitor`` from the bus of ``config`` until Ctrl-C or SIGTERM (raised as
    KeyboardInterrupt, caught here: the state is kept), or, with ``once``, until every axis has
    closed a window, or until ``stop`` is set (another thread's way to end it).  ``opener`` opens
    the bus (default: bus.yml's interface and channel).

    Parameters
    ----------
    monitor : Monitor
        The monitor fed.
    config : BusConfig
        The bus configuration.
    say : callable
        Where lines for the user go.
    once : bool
        Until every axis has closed a window.
    opener : callable, optional
        Opens the bus.
    stop : threading.Event, optional
        Set by another thread to end it.

    Returns
    -------
    Listening
        What it saw, and how it ended.
    """
    m = config.master
    if opener is None and m.interface is None:
        raise UserError(
            f"{config.path}: no CAN interface named: give master.interface (and channel) in bus.yml, "
            f"-i/--interface and -c/--channel, or python-can's configuration (CAN_INTERFACE, ~/.canrc)"
        )
    interface = str(m.interface)
    where = f"{m.interface}:{m.channel}"
    open_raw = opener or (lambda: open_bus(interface, m.channel, m.bitrate, m.can_options))
    seen = Listening()
    bus: ListenOnly | None = None
    closed_before = dict(monitor.closed)
    stamp: float | None = None  # the last frame's time stamp [s] and when it came (monotonic)
    at = 0.0
    try:
        while True:
            if bus is None:
                try:
                    bus = ListenOnly(open_raw())
                except Exception as exc:  # python-can raises many kinds for an adapter that is gone
                    say(f"bus {where}: cannot open ({exc}); trying again in {RETRY_S:g} s")
                    time.sleep(RETRY_S)
                    seen.reconnections += 1
                    continue
                say(
                    f"listening on {where if opener is None else bus.inner_info} "
                    + ("(adapter in listen-only mode)" if bus.hardware_passive else "(never sending)")
                )
            try:
                msg = bus.recv(RECV_S)
            except (can.CanError, OSError) as exc:
                say(f"bus {where} lost ({exc}); reopening in {RETRY_S:g} s")
                _close(bus)
                bus = None
                time.sleep(RETRY_S)
                seen.reconnections += 1
                continue
            if msg is not None:
                seen.frames += 1
                if msg.is_error_frame:
                    seen.error_frames += 1
                    if seen.error_frames in (1, 10, 100, 1000) or seen.error_frames % 10000 == 0:
                        say(f"{seen.error_frames} error frame(s) on the bus so far; listening on")
                else:
                    monitor.listener.on_message_received(msg)
                stamp, at = msg.timestamp, time.monotonic()
            if stamp is not None:  # on the adapter's clock: the last frame's stamp and the time since
                monitor.tick(stamp + time.monotonic() - at)
            if (once and _every_axis_closed(monitor, closed_before)) or (stop is not None and stop.is_set()):
                break
    except KeyboardInterrupt as exc:
        seen.stopped_by = getattr(exc, "name", "Ctrl-C")
    finally:
        if bus is not None:
            _close(bus)
        monitor.stop()
    return seen


def _every_axis_closed(monitor: Monitor, before: dict[str, int]) -> bool:
    return all(n > before[axis] for axis, n in monitor.closed.items())


def _close(bus: can.BusABC) -> None:
    try:
        bus.shutdown()
    except Exception as exc:  # a bus already gone
        log.debug("bus shutdown: %s", exc)
