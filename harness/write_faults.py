"""The faults injected into a parameter write over two simulated drives: every phase of the
transaction (backup, write, verify, store, restore) failing in every way a real bus can (an SDO
abort, the drive gone, Ctrl-C, a read-back that disagrees); the values written and how a drive's
set is read back."""

from __future__ import annotations

import canopen

from drive_bridge.params.profile import load_profile
from drive_bridge.params.read import sdo_variable
from drive_bridge.tuning.design import design_gains

from .support import PAPER

SIM = load_profile("drive_bridge_servo")
NAMES = ("KpP", "KpS", "KiS", "J", "c0", "c1", "ff_enable")


def new_values(axis: str) -> dict[str, float]:
    p = PAPER[axis]
    gains = design_gains(p["J"], p["c1"], 0.8, 0.002).gains()
    return {"KpP": gains["KpP"], "KpS": gains["KpS"], "KiS": gains["KiS"], **p, "ff_enable": 1.0}


def device(node) -> dict[str, float]:
    return {n: sdo_variable(node, SIM.entries[n]).raw for n in NAMES}


class Fault:
    """Injected into drive y: fires once, on the first SDO request of ``phase``, as ``kind``.

    Phases follow the transaction's order on the bus: backup (reads), write (writes of the
    parameters), verify (reads after the writes), store (write of 0x1010), restore (writes after
    the fault fired)."""

    def __init__(self, drive, phase: str, kind: str):
        self.drive, self.phase, self.kind = drive, phase, kind
        self.seen, self.fired, self.after = "backup", False, 0

    def __call__(self, op: str, index: int, sub: int):
        if self.fired:
            self.after += op == "write"
            if self.phase == "restore" and self.after == 1:
                return self._fire(op, index)
            return None
        if op == "write":
            self.seen = "store" if index == 0x1010 else "write"
        elif self.seen == "write":
            self.seen = "verify"
        if self.seen == self.phase or (self.phase == "restore" and self.seen == "verify"):
            if self.phase == "restore":  # first make the transaction fail, then hit its restore
                self.fired = True
                raise canopen.SdoAbortedError(0x08000020)
            self.fired = True
            return self._fire(op, index)
        return None

    def _fire(self, op, index):
        if self.kind == "abort":
            raise canopen.SdoAbortedError(0x06090030)
        if self.kind == "lost":
            self.drive.online = False
            return None
        if self.kind == "ctrl-c":
            raise KeyboardInterrupt
        if self.kind == "mismatch":
            return 12345  # the drive answers another value than was written
        raise AssertionError(self.kind)


CASES = [
    (phase, kind)
    for phase in ("backup", "write", "verify", "store", "restore")
    for kind in ("abort", "lost", "ctrl-c", "mismatch")
    if not (kind == "mismatch" and phase != "verify")
]
