"""CiA 402 vocabulary, one for the master and the simulated drives: the power states and the
statusword bits that show them, the controlwords that command them, the operating modes and the
option codes of the reactions a drive can be set to.

canopen's :class:`~canopen.profiles.p402.State402` names the states as the master sees them;
:func:`state_name` reads a statusword with its masks.  The states' numbers here are the drive's
side (:mod:`drive_bridge.sim.state_machine` runs the transitions between them).
"""

from __future__ import annotations

from canopen.profiles.p402 import State402

# -- controlwords (0x6040) -----------------------------------------------------------------------
CW_SHUTDOWN, CW_SWITCH_ON, CW_ENABLE = 0x06, 0x07, 0x0F
CW_QUICK_STOP = 0x000B  # enable voltage + switch on + enable operation, quick stop bit low
CW_DISABLE_VOLTAGE = 0x0000
CW_HALT_BIT = 0x0100  # controlword bit 8: halt
CW_HALT = 0x010F  # enable operation with halt (bit 8): a profile position drive holds
CW_FAULT_RESET = 0x80
CW_ENABLE_IP = 0x1F  # enable operation + bit 4: enable interpolation

# -- statusword (0x6041) -------------------------------------------------------------------------
SW_FAULT = 0x0008
SW_VOLTAGE_ENABLED = 0x0010
SW_REMOTE = 0x0200
SW_TARGET_REACHED = 0x0400
SW_INTERNAL_LIMIT = 0x0800
# bits 12 and 13 mean what the operating mode says
SW_FOLLOWING = 0x1000  # CSP follows the setpoints / IP active / PP set-point acknowledged
SW_FOLLOWING_ERROR = 0x2000  # CSP, PP: following error
SW_SPEED_ZERO = 0x1000  # profile velocity: the speed is 0 (inside the velocity threshold 0x606F)
SW_HOMING_ATTAINED = 0x1000  # homing
SW_HOMING_ERROR = 0x2000  # homing

#: the power states, the drive's side
NOT_READY, SWITCH_ON_DISABLED, READY, SWITCHED_ON, ENABLED, QUICK_STOP, FAULT_REACTION, FAULT = range(8)
#: statusword bits 0-3, 5, 6 of each state
STATE_BITS = {
    NOT_READY: 0x00,
    SWITCH_ON_DISABLED: 0x40,
    READY: 0x21,
    SWITCHED_ON: 0x23,
    ENABLED: 0x27,
    QUICK_STOP: 0x07,
    FAULT_REACTION: 0x0F,
    FAULT: 0x08,
}
#: states in which the power stage has voltage (statusword bit 4)
VOLTAGE_ENABLED = (READY, SWITCHED_ON, ENABLED, QUICK_STOP, FAULT_REACTION)

# -- modes of operation (0x6060, 0x6061, 0x6502) -------------------------------------------------
PP, PV, HM, IP, CSP = 1, 3, 6, 7, 8
MODE_NAMES = {
    PP: "profile position",
    2: "velocity",
    PV: "profile velocity",
    4: "profile torque",
    HM: "homing",
    IP: "interpolated position",
    CSP: "cyclic synchronous position",
    9: "cyclic synchronous velocity",
    10: "cyclic synchronous torque",
}

# -- option codes --------------------------------------------------------------------------------
#: abort connection (0x6007): what a drive does when it loses its master
ABORT_FAULT, ABORT_DISABLE, ABORT_QUICK_STOP = 1, 2, 3
#: quick stop option (0x605A): ramp on the quick-stop deceleration and stay in QUICK STOP ACTIVE
QUICK_STOP_RAMP_AND_HOLD = 6
#: quick stop options that stay in QUICK STOP ACTIVE
QUICK_STOP_STAYS = (5, 6, 7, 8)
#: fault reaction option (0x605E): ramp down on the quick-stop deceleration
FAULT_REACTION_QUICK_STOP_RAMP = 2


def state_name(statusword: int) -> str:
    """Name of the CiA 402 state a statusword shows (canopen's names).

    Parameters
    ----------
    statusword : int
        0x6041's value.

    Returns
    -------
    str
        ``OPERATION ENABLED``, ...; ``UNKNOWN (0x....)`` for none.
    """
    for name, (mask, value) in State402.SW_MASK.items():
        if statusword & mask == value:
            return name
    return f"UNKNOWN (0x{statusword:04X})"
