"""The CiA 402 power state machine of a simulated drive (the drive's side), as tables.

The states and their statusword bits are the protocol floor's (:mod:`drive_bridge.cia.p402`);
this is the drive's side of the machine: the
device control commands decoded from the controlword as CiA 402 defines them
(bits 7, 3, 2, 1, 0), and the transition each command makes from each state.
A fault reset is the rising edge of bit 7 in FAULT.  Quick stop returns to
OPERATION ENABLED on "enable operation" only when the quick stop option code
(0x605A) says the drive stays in QUICK STOP ACTIVE (5..8).
"""

from __future__ import annotations

from ..cia.p402 import ENABLED, FAULT, QUICK_STOP, QUICK_STOP_STAYS, READY, SWITCH_ON_DISABLED, SWITCHED_ON

#: device control commands: (name, mask, value) of the controlword
COMMANDS = (
    ("disable voltage", 0x82, 0x00),
    ("quick stop", 0x86, 0x02),
    ("shutdown", 0x87, 0x06),
    ("switch on", 0x8F, 0x07),  # also "disable operation" from OPERATION ENABLED
    ("enable operation", 0x8F, 0x0F),
)

#: (command, state) -> next state; a command not listed for a state leaves it unchanged
TRANSITIONS = {
    **{("disable voltage", s): SWITCH_ON_DISABLED for s in (READY, SWITCHED_ON, ENABLED, QUICK_STOP)},
    ("quick stop", READY): SWITCH_ON_DISABLED,
    ("quick stop", SWITCHED_ON): SWITCH_ON_DISABLED,
    ("quick stop", ENABLED): QUICK_STOP,
    **{("shutdown", s): READY for s in (SWITCH_ON_DISABLED, SWITCHED_ON, ENABLED)},
    ("switch on", READY): SWITCHED_ON,
    ("switch on", ENABLED): SWITCHED_ON,
    ("enable operation", READY): ENABLED,
    ("enable operation", SWITCHED_ON): ENABLED,
    ("enable operation", QUICK_STOP): ENABLED,
}


def command(controlword: int) -> str | None:
    """The device control command a controlword gives (None: none, e.g. bit 7 set).

    Parameters
    ----------
    controlword : int
        0x6040's value.

    Returns
    -------
    str or None
        The command.
    """
    return next((name for name, mask, value in COMMANDS if controlword & mask == value), None)


def next_state(state: int, controlword: int, previous: int, quick_stop_option: int) -> int:
    """The state after ``controlword`` (``previous`` is the controlword before it).

    Parameters
    ----------
    state : int
        The state now.
    controlword : int
        The controlword.
    previous : int
        The controlword before it (a fault reset is its bit 7's rising edge).
    quick_stop_option : int
        0x605A.

    Returns
    -------
    int
        The next state.
    """
    if state == FAULT:
        return SWITCH_ON_DISABLED if controlword & 0x80 and not previous & 0x80 else FAULT
    cmd = command(controlword)
    if cmd is None:
        return state
    if cmd == "enable operation" and state == QUICK_STOP and quick_stop_option not in QUICK_STOP_STAYS:
        return state
    return TRANSITIONS.get((cmd, state), state)
