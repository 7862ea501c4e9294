"""CiA 402 power state machine of one drive over SDO: its state, a fault reset, the operating mode,
a command for a mode the drive runs on its own (homing); enabling and stopping a streamed motion go
in the cyclic controlword (:mod:`.stream`).

canopen's BaseNode402 has fixed timeouts and a mode switch that can fail
silently; here every wait uses the link clock and a configured timeout, the
mode switch is confirmed through 0x6061, and every failure says what the
drive showed.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import canopen

from ..cia.objects import CONTROLWORD, ERROR_CODE, MODES_OF_OPERATION, MODES_OF_OPERATION_DISPLAY, STATUSWORD
from ..cia.p402 import CW_ENABLE, CW_FAULT_RESET, CW_SHUTDOWN, CW_SWITCH_ON, SW_FAULT, state_name
from ..errors import BusError, DriveRefused

if TYPE_CHECKING:
    from .timing import Clock


class Drive402:
    """Power state machine of ``node`` with waits on ``clock`` bounded by ``timeout`` [s].

    Parameters
    ----------
    node : canopen.RemoteNode
        The drive.
    axis : str
        Its axis, for the errors.
    clock : Clock
        The link's clock.
    timeout : float
        How long a state change is waited for [s].
    """

    def __init__(self, node: canopen.RemoteNode, axis: str, clock: Clock, timeout: float):
        self.node = node
        self.axis = axis
        self.clock = clock
        self.timeout = timeout

    def statusword(self) -> int:
        """0x6041, read by SDO.

        Returns
        -------
        int
            The statusword.
        """
        return self.node.sdo[STATUSWORD].raw

    def state(self) -> str:
        """The CiA 402 state the drive shows now.

        Returns
        -------
        str
            ``OPERATION ENABLED``, ...
        """
        return state_name(self.statusword())

    def _wait_for(self, target: str, doing: str) -> None:
        deadline = self.clock.now() + self.timeout
        while True:
            sw = self.statusword()
            if state_name(sw) == target:
                return
            if sw & SW_FAULT and target != "FAULT":
                raise BusError(
                    f"axis {self.axis}: drive went to FAULT while {doing} "
                    f"(error code 0x{self.node.sdo[0x603F].raw:04X})"
                )
            if self.clock.now() >= deadline:
                raise BusError(
                    f"axis {self.axis}: drive did not reach {target} within {self.timeout} s "
                    f"while {doing}; it shows {state_name(sw)} (statusword 0x{sw:04X})"
                )
            self.clock.sleep(0.005)

    def command(self, controlword: int, target: str, doing: str) -> None:
        """Write ``controlword`` by SDO and wait for the state ``target`` (BusError naming what the
        drive shows otherwise); for a mode the drive runs on its own, such as homing.

        Parameters
        ----------
        controlword : int
            0x6040's value.
        target : str
            The state to wait for.
        doing : str
            What it is for, for the error.

        Raises
        ------
        BusError
            The drive does not reach the state within the timeout.
        """
        self.node.sdo[CONTROLWORD].raw = controlword
        self._wait_for(target, doing)

    def enable(self, doing: str, operation: int = CW_ENABLE) -> None:
        """Shutdown, switch on, then ``operation`` (enable operation, with halt where the drive is to
        hold) by SDO, each waited for in the state it leads to; for a mode the drive runs on its own.

        Parameters
        ----------
        doing : str
            What it is for, for the error.
        operation : int
            The controlword that enables operation.

        Raises
        ------
        BusError
            The drive does not reach a state within the timeout.
        """
        self.command(CW_SHUTDOWN, "READY TO SWITCH ON", doing)
        self.command(CW_SWITCH_ON, "SWITCHED ON", doing)
        self.command(operation, "OPERATION ENABLED", doing)

    def reset_fault(self) -> None:
        """Reset a fault, where the drive shows one, and wait for SWITCH ON DISABLED.

        Raises
        ------
        DriveRefused
            A fault that does not clear with a fault reset.
        """
        if not self.statusword() & SW_FAULT:
            return
        code = self.node.sdo[ERROR_CODE].raw
        self.node.sdo[CONTROLWORD].raw = 0x00
        self.node.sdo[CONTROLWORD].raw = CW_FAULT_RESET
        try:
            self._wait_for("SWITCH ON DISABLED", f"resetting fault 0x{code:04X}")
        except BusError as exc:
            raise DriveRefused(
                f"axis {self.axis}: fault 0x{code:04X} does not clear with a fault reset; "
                f"find and remove its cause at the drive"
            ) from exc

    def set_mode(self, mode: int) -> None:
        """Select the operating mode and confirm it in 0x6061 (no silent failure).

        Parameters
        ----------
        mode : int
            The mode (0x6060).

        Raises
        ------
        DriveRefused
            The drive refuses it.
        BusError
            0x6061 does not show it within the timeout.
        """
        try:
            self.node.sdo[MODES_OF_OPERATION].raw = mode
        except canopen.SdoAbortedError as exc:
            raise DriveRefused(f"axis {self.axis}: drive refused operating mode {mode} ({exc})") from exc
        deadline = self.clock.now() + self.timeout
        while (shown := self.node.sdo[MODES_OF_OPERATION_DISPLAY].raw) != mode:
            if self.clock.now() >= deadline:
                raise BusError(
                    f"axis {self.axis}: mode {mode} requested, drive still shows {shown} "
                    f"in 0x6061 after {self.timeout} s"
                )
            self.clock.sleep(0.005)
