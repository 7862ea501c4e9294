"""``reference: home``: the drive's own homing (CiA 402 homing mode 6), before an axis's first motion.

The method (0x6098), speeds (0x6099:1 toward the switch, :2 toward zero) and acceleration
(0x609A) of the node's ``homing`` section are written in the drive's units and read back; the
drive is enabled in homing mode by SDO and started with controlword bit 4; the master then
watches the statusword (bit 12 homing attained with bit 10 target reached: done; bit 13:
homing error), the drive's heartbeat and the timeout.  Anything else -- a fault, an error, the
timeout, Ctrl-C, SIGTERM -- quick-stops the axis where it is and ends the command as a motion
stop; nothing streams until every axis that needs it is homed.  Afterwards the axis is held as
any other: on its brake (``holding: brake``), or powered where homing left it.
"""

from __future__ import annotations

import logging

from ..cia.objects import CONTROLWORD, HOMING_ACCELERATION, HOMING_METHOD, HOMING_SPEEDS
from ..cia.p402 import (
    CW_ENABLE,
    CW_SHUTDOWN,
    HM,
    SW_FAULT,
    SW_HOMING_ATTAINED,
    SW_HOMING_ERROR,
    SW_TARGET_REACHED,
)
from ..cia.sdo import write_setting
from ..config import BusConfig
from ..errors import Interrupted, MotionAborted
from ..interrupts import signal_name
from .bringup import AxisLink, read_back
from .hold import quick_stop
from .link import Link
from .supervision import check_heartbeats

log = logging.getLogger(__name__)

CW_START = CW_ENABLE | 0x10  # enable operation with bit 4: start homing
POLL_S = 0.01


def to_home(axes: dict[str, AxisLink]) -> list[str]:
    """The axes that home before they move (``reference: home``) and have not in this bring-up.

    Parameters
    ----------
    axes : dict of str to AxisLink
        The brought-up axes.

    Returns
    -------
    list of str
        Those axes.
    """
    return [a for a, ax in axes.items() if ax.cfg.homing is not None and not ax.homed]


def home(link: Link, axes: dict[str, AxisLink], config: BusConfig) -> None:
    """Home each axis of :func:`to_home`, one after the other; MotionAborted (the axis quick-stopped
    and held) when one does not home.

    Parameters
    ----------
    link : Link
        The link to the drives.
    axes : dict of str to AxisLink
        The brought-up axes.
    config : BusConfig
        The bus configuration.

    Raises
    ------
    MotionAborted
        An axis that does not home (quick-stopped and held).
    """
    for name in to_home(axes):
        _home(link, axes[name], config)


def _home(link: Link, ax: AxisLink, config: BusConfig) -> None:
    h, sc, node, drive = ax.cfg.homing, ax.cfg.scaling, ax.node, ax.drive
    if h is None:
        raise ValueError(f"axis {ax.name} has no homing configured")  # to_home only names axes that have
    vel = sc.velocity_per_rad_s
    settings = [
        (HOMING_METHOD, 0, h.method),
        (HOMING_SPEEDS, 1, round(h.switch_speed * vel)),
        (HOMING_SPEEDS, 2, round(h.zero_speed * vel)),
        (HOMING_ACCELERATION, 0, round(h.acceleration * vel)),
    ]
    for index, sub, value in settings:
        write_setting(node, ax.name, index, sub, value)
    read_back(node, ax.name, settings)
    log.info(
        "axis %s: homing, method %d, %.4g / %.4g rad/s, %.4g rad/s², within %g s",
        ax.name,
        h.method,
        h.switch_speed,
        h.zero_speed,
        h.acceleration,
        h.timeout_s,
    )
    drive.reset_fault()
    drive.set_mode(HM)
    clock = link.clock
    try:
        drive.enable("enabling for homing")
        node.sdo[CONTROLWORD].raw = CW_START
        deadline = clock.now() + h.timeout_s
        while True:
            clock.sleep(POLL_S)
            sw = drive.statusword()
            if sw & SW_FAULT:
                raise MotionAborted(
                    f"the drive faulted while homing (error code 0x{node.sdo[0x603F].raw:04X})", ax.name
                )
            if sw & SW_HOMING_ERROR:
                raise MotionAborted(
                    f"the drive reports a homing error (statusword 0x{sw:04X}): check homing.method "
                    f"{h.method} against how the axis is wired",
                    ax.name,
                )
            if sw & SW_HOMING_ATTAINED and sw & SW_TARGET_REACHED:
                break
            lost = check_heartbeats({ax.name: ax}, [ax.name], clock.now(), config.master.heartbeat_timeout_s)
            if lost is not None:
                raise lost
            if clock.now() > deadline:
                raise MotionAborted(
                    f"not homed within homing.timeout_s = {h.timeout_s:g} s (statusword 0x{sw:04X})", ax.name
                )
        node.sdo[CONTROLWORD].raw = CW_ENABLE  # bit 4 down: homing done, the drive holds
        if ax.cfg.drive_limits is not None and ax.cfg.drive_limits.holding == "brake":
            drive.command(CW_SHUTDOWN, "READY TO SWITCH ON", "putting the axis on its brake after homing")
    except (KeyboardInterrupt, Exception) as exc:
        problems = quick_stop(link, {ax.name: ax}, max(config.master.state_timeout_s, 2.0))
        detail = "".join(f"; {p}" for p in problems)
        if isinstance(exc, KeyboardInterrupt):
            raise Interrupted(f"axis {ax.name} was homing{detail}", signal_name(exc)) from exc
        reason = exc.reason if isinstance(exc, MotionAborted) else f"homing failed ({exc})"
        raise MotionAborted(f"{reason}; quick-stopped{detail}", ax.name) from exc
    ax.homed = True
    log.info("axis %s: homed, at %.6g rad", ax.name, ax.position_rad())
