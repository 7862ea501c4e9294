"""Who keeps time while the master streams: the SYNC producer, chosen per run and said.

On the wall clock the first choice is a drive that can produce SYNC (its EDS/DCF has COB-ID SYNC
0x1005 writable and the communication cycle period 0x1006): it sends every SYNC on its own clock,
whatever the master's host does, and the master answers each SYNC as the bus shows it.  Else the
interface sends SYNC where it sends periodic frames itself (the kernel's broadcast manager on
socketcan, an adapter's cyclic list: :func:`.port.periodic_send_of`), and last the engine's own
loop -- the host-timed mode, whose stalls stop the SYNCs.  In lockstep the master's SYNC is on
time by construction.

The drive produces SYNC only while the engine streams: :func:`producing` sets bit 30 of its
0x1005 for that long (0x1006 holds the period since bring-up) and clears it on every way out.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Iterator
from contextlib import contextmanager

import canopen

from ..cia.objects import COB_ID_SYNC, CYCLE_PERIOD
from ..cia.p301 import SYNC_COB_ID, SYNC_PRODUCER
from ..errors import MotionAborted
from .bringup import AxisLink

log = logging.getLogger(__name__)


def can_produce(ax: AxisLink) -> bool:
    """The axis's drive can produce SYNC, as its EDS/DCF says (0x1005 writable, 0x1006 present).

    Parameters
    ----------
    ax : AxisLink
        The axis.

    Returns
    -------
    bool
        It can.
    """
    od = ax.cfg.od
    cob_id = od.get_variable(COB_ID_SYNC, 0)
    return cob_id is not None and cob_id.writable and od.get_variable(CYCLE_PERIOD, 0) is not None


def choose_producer(axes: dict[str, AxisLink], wall_clock: bool, choice: str = "auto") -> AxisLink | None:
    """The axis whose drive produces SYNC in this run (None: the interface or the master does).

    On the wall clock, the first axis that can, unless ``choice`` (bus.yml ``master.sync_producer``)
    is ``interface``; in lockstep none.

    Parameters
    ----------
    axes : dict of str to AxisLink
        The brought-up axes (the chosen one is marked ``sync_producer``).
    wall_clock : bool
        The run is on the wall clock.
    choice : {"auto", "interface"}
        bus.yml's ``master.sync_producer``.

    Returns
    -------
    AxisLink or None
        The producer.
    """
    producer = (
        next((ax for ax in axes.values() if can_produce(ax)), None)
        if wall_clock and choice == "auto"
        else None
    )
    for ax in axes.values():
        ax.sync_producer = ax is producer
    return producer


def described(ax: AxisLink) -> str:
    """The drive producing SYNC, in words (what the run records as its SYNC source).

    Parameters
    ----------
    ax : AxisLink
        The producer.

    Returns
    -------
    str
        The words.
    """
    return f"drive {ax.name} (node {ax.cfg.node_id}), on its own clock (0x1005 bit 30)"


#: how long the drive's first SYNC is waited for once told to produce it [s]
FIRST_SYNC_S = 0.5


@contextmanager
def producing(ax: AxisLink | None) -> Iterator[bool]:
    """``ax``'s drive producing SYNC for as long as the block runs (nothing where None); whether it
    does: a drive whose SYNC does not show within :data:`FIRST_SYNC_S` (an EDS that promises more
    than the drive does) is told to stop again, and the caller's engine sends SYNC instead.

    Parameters
    ----------
    ax : AxisLink or None
        The producer.

    Yields
    ------
    bool
        The drive produces SYNC.

    Raises
    ------
    MotionAborted
        The drive refused to produce SYNC (nothing was enabled).
    """
    if ax is None:
        yield False
        return
    network = ax.node.network
    seen = threading.Event()

    def on_sync(cob_id: int, data: bytearray, timestamp: float) -> None:
        seen.set()

    network.subscribe(SYNC_COB_ID, on_sync)
    try:
        try:
            ax.node.sdo[COB_ID_SYNC].raw = SYNC_COB_ID | SYNC_PRODUCER
        except (canopen.SdoCommunicationError, canopen.SdoAbortedError) as exc:
            raise MotionAborted(
                f"making the drive the SYNC producer (0x1005 bit 30) failed ({exc}); nothing was enabled",
                ax.name,
            ) from exc
        produces = _waited(seen, ax)
    finally:
        network.unsubscribe(SYNC_COB_ID, on_sync)
    if not produces:
        log.warning(
            "axis %s: its drive sent no SYNC within %g s of 0x1005 bit 30: the master sends SYNC instead",
            ax.name,
            FIRST_SYNC_S,
        )
    try:
        yield produces
    finally:
        try:
            ax.node.sdo[COB_ID_SYNC].raw = SYNC_COB_ID
        except (canopen.SdoCommunicationError, canopen.SdoAbortedError) as exc:
            log.warning(
                "axis %s: its drive may still produce SYNC: clearing 0x1005 bit 30 failed (%s)", ax.name, exc
            )


def _waited(seen: threading.Event, ax: AxisLink) -> bool:
    """Whether the drive's first SYNC came within :data:`FIRST_SYNC_S` (on the link's clock); where
    it did not, bit 30 is cleared again before the engine sends SYNC itself."""
    clock = ax.drive.clock
    deadline = clock.now() + FIRST_SYNC_S
    while not seen.is_set() and clock.now() < deadline:
        clock.sleep(0.005)
    if seen.is_set():
        return True
    try:
        ax.node.sdo[COB_ID_SYNC].raw = SYNC_COB_ID
    except (canopen.SdoCommunicationError, canopen.SdoAbortedError) as exc:
        raise MotionAborted(
            f"its drive sent no SYNC within {FIRST_SYNC_S} s of 0x1005 bit 30, and clearing the bit "
            f"failed ({exc}); nothing was enabled",
            ax.name,
        ) from exc
    return False
