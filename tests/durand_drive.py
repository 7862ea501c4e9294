"""Strict CiA 402 slaves on a CANopen stack drive-bridge did not write: durand (MIT, PyPI), a
pure-Python CiA 301 responder on python-can.

A slave is built from a vendor's EDS/DCF: only the objects the file lists, with their data types,
access types and limits (durand's SDO server refuses what they forbid), PDO mappings only of
objects the file marks PDO-mappable, as many PDOs as the file has.  On top, the least of CiA 402 a
master needs to stream: the power state machine driven by the controlword, the mode shown in
0x6061, and an ideal axis that stands where its last setpoint (0x607A, or an interpolation
record) put it, sampled at SYNC.  What is checked is the protocol: every SDO, PDO and NMT exchange
of scan, bring-up, a campaign, a write and a store against an independent implementation.
"""

from __future__ import annotations

import itertools
import threading
from functools import cache

import can
import canopen
from durand import CANBusNetwork, DatatypeEnum, Node, Record, Variable, set_scheduler
from durand.node import NodeCapabilities
from durand.scheduler import SyncScheduler
from durand.services.nmt import StateEnum

from drive_bridge.cia.od import load_od
from drive_bridge.cia.setpoint import unpack_pvt
from drive_bridge.sim.vendors import spec_for

ACCESS = {"rw": "rw", "rww": "rw", "rwr": "rw", "ro": "ro", "wo": "wo", "const": "const"}
#: what durand's own services hold (their values come from the EDS where it gives them)
DURAND_OWNS = set(range(0x1400, 0x1C00)) | {0x1005, 0x1017, 0x1200, 0x1021, 0x1022}
#: CiA 402 statusword of each state, and the controlword command that leads out of it
STATUS = {"SOD": 0x0250, "READY": 0x0231, "ON": 0x0233, "ENABLED": 0x0237, "QUICK STOP": 0x0217}
_channels = itertools.count(1)


@cache
def _timers() -> None:
    """durand's timers (heartbeat, inhibit times) on a thread of their own (its default needs asyncio)."""
    scheduler = SyncScheduler()
    set_scheduler(scheduler)

    def run() -> None:
        while True:
            try:
                scheduler.run()
            except can.CanError:  # a timer of a slave whose bus was closed meanwhile
                pass

    threading.Thread(target=run, name="durand-timers", daemon=True).start()


def _variable(var: canopen.objectdictionary.ODVariable) -> Variable:
    dt = DatatypeEnum(var.data_type)
    numeric = var.data_type not in (0x09, 0x0A, 0x0F)
    value = var.default if var.default is not None else (0 if numeric else b"")
    if numeric and var.min is not None:
        value = max(value, var.min)
    if numeric and var.max is not None:
        value = min(value, var.max)
    limits = {"minimum": var.min, "maximum": var.max} if numeric else {}
    return Variable(dt, ACCESS[var.access_type], value, name=var.name, **limits)


class DurandDrive:
    """One slave on its own python-can connection to ``channel`` (durand's network keeps one
    subscriber per COB-ID, so each node gets a network of its own)."""

    def __init__(self, eds, node_id: int, channel: str, serial: int = 0):
        _timers()
        od = load_od(eds, node_id)
        count = lambda base: sum(1 for i in range(base, base + 0x200) if i in od)  # noqa: E731
        self.bus = can.Bus(interface="virtual", channel=channel, receive_own_messages=False)
        self.network = CANBusNetwork(self.bus)
        self.node = Node(
            self.network, node_id, capabilities=NodeCapabilities(1, count(0x1400), count(0x1800))
        )
        d = self.node.object_dictionary
        for obj in od.values():
            if obj.index in DURAND_OWNS:
                continue
            if isinstance(obj, canopen.objectdictionary.ODVariable):
                d[obj.index] = _variable(obj)
            else:
                rec = Record(name=obj.name)
                for sub, var in obj.subindices.items():
                    if sub:
                        rec[sub] = _variable(var)
                d[obj.index] = rec
        for comm in range(0x1400, 0x1A00):  # sub-indices the file has and durand's PDOs lack
            if comm in od and (comm & 0xFF00) in (0x1400, 0x1800) and comm in d:
                for sub, var in od[comm].subindices.items():
                    if sub and sub not in d[comm]:
                        d[comm][sub] = _variable(var)  # held, not acted on (durand has no event timer)
        if od[0x1000].default is None:  # the drive reports what the file leaves out
            d.write(0x1000, 0, 0x00020192)  # CiA 402, servo drive
        if 0x6502 in od and od[0x6502].default is None:  # the modes the vendor documents (sim/vendors.py)
            d.write(0x6502, 0, spec_for(eds).supported_modes)
        info = od.device_information
        for sub, value in (
            (1, info.vendor_number),
            (2, info.product_number),
            (3, info.revision_number),
            (4, serial),
        ):
            d.write(0x1018, sub, value or 0)
        self.od = od
        for comm in range(0x1400, 0x1C00):  # mapping entries: only PDO-mappable objects
            if (comm & 0xFF00) in (0x1600, 0x1A00) and comm in od:
                for sub in range(1, 9):
                    d.validate_callbacks[(comm, sub)].add(self._mappable)
        self.state = "SOD"
        self.position = self.target = 0
        d.write(0x6041, 0, STATUS["SOD"])
        d.update_callbacks[(0x6040, 0)].add(self._controlword)
        d.update_callbacks[(0x6060, 0)].add(lambda mode: d.write(0x6061, 0, mode))
        self.node.sync.callbacks.add(self._on_sync)
        self.node.nmt.set_state(StateEnum.PRE_OPERATIONAL)

    def _mappable(self, value: int) -> None:
        index, sub, bits = value >> 16, (value >> 8) & 0xFF, value & 0xFF
        var = self.od.get_variable(index, sub)
        if value and (var is None or not var.pdo_mappable or len(var) != bits):
            raise ValueError(f"0x{index:04X}:{sub} cannot be mapped as {bits} bits")

    def _controlword(self, cw: int) -> None:
        d = self.node.object_dictionary
        command = cw & 0x8F
        if cw & 0x86 == 0x02 and self.state == "ENABLED":  # quick stop
            self.state = "QUICK STOP"
        elif not cw & 0x02:  # disable voltage
            self.state = "SOD"
        elif command & 0x87 == 0x06:  # shutdown
            self.state = "READY"
        elif command == 0x07 and self.state in ("READY", "ENABLED"):
            self.state = "ON"
        elif command == 0x0F and self.state in ("ON", "READY", "ENABLED", "QUICK STOP"):
            if self.state != "ENABLED":
                self.target = self.position  # takes the target as it stands
            self.state = "ENABLED"
        following = self.state == "ENABLED" and (d.read(0x6061, 0) == 8 or cw & 0x10)
        d.write(0x6041, 0, STATUS[self.state] | (0x1000 if following else 0))

    def _on_sync(self) -> None:
        d = self.node.object_dictionary
        if self.state == "ENABLED":
            if d.read(0x6061, 0) == 8 and 0x607A in self.od:
                self.target = d.read(0x607A, 0)
            elif 0x20C1 in self.od:
                self.target = unpack_pvt(d.read(0x20C1, 0))[0]
        velocity, self.position = self.target - self.position, self.target
        d.write(0x6064, 0, self.position)
        if 0x606C in self.od:
            d.write(0x606C, 0, max(-(2**31), min(2**31 - 1, velocity * 500)))

    def close(self) -> None:
        self.node.object_dictionary.write(0x1017, 0, 0)  # its heartbeat timer off first
        self.network.stop()
        self.bus.shutdown()


def slaves(eds, node_ids: dict[str, int]) -> tuple[str, list[DurandDrive]]:
    """A private virtual channel with one durand slave per axis: (channel, slaves)."""
    channel = f"durand-{next(_channels)}"
    return channel, [DurandDrive(eds, n, channel, serial=1000 + n) for n in node_ids.values()]
