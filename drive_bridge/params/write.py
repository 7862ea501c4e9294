"""Transactional parameter write: backup, write all, read back and compare, then store.

Nothing is half-written: any failure (SDO abort, time-out, a value out of the
data type's range, a read-back that differs) restores the backup and issues
no store; only when every value is verified is 0x1010 'save' written.  The
result lists every object with its old and new value in SI and device units.
"""
from __future__ import annotations

import json
import struct
from dataclasses import asdict, dataclass, field
from pathlib import Path

import canopen
from canopen.objectdictionary import datatypes
from canopen.sdo import SdoVariable

from ..errors import DriveRefused
from .profile import Entry, Profile
from .read import SDO_ERRORS, describe_sdo_error, require_profile_objects, sdo_variable

SAVE_SIGNATURE = 0x65766173         # "save"
_RANGES = {datatypes.UNSIGNED8: (0, 2**8 - 1), datatypes.UNSIGNED16: (0, 2**16 - 1),
           datatypes.UNSIGNED32: (0, 2**32 - 1), datatypes.INTEGER8: (-2**7, 2**7 - 1),
           datatypes.INTEGER16: (-2**15, 2**15 - 1), datatypes.INTEGER32: (-2**31, 2**31 - 1)}


@dataclass
class ObjectWrite:
    parameter: str
    index: int
    sub: int
    unit: str
    old_si: float | None = None
    new_si: float | None = None
    old_device: float | int | None = None
    new_device: float | int | None = None
    written: bool = False
    verified: bool = False


@dataclass
class WriteResult:
    """What happened; ``ok`` only when every object was written, verified (and stored if asked)."""

    node_id: int
    drive: str
    objects: list[ObjectWrite]
    unsupported: list[str]
    dry_run: bool = False
    stored: bool = False
    restored: bool = False
    error: str | None = None
    backup: str | None = None
    notes: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return self.error is None

    def as_dict(self) -> dict:
        d = asdict(self)
        d["ok"] = self.ok
        return d


def _same(entry: Entry, a, b) -> bool:
    if entry.is_integer:
        return int(a) == int(b)
    f32 = entry.type == "REAL32"
    pack = (lambda x: struct.unpack("<f", struct.pack("<f", x))[0]) if f32 else float
    return pack(float(a)) == pack(float(b))


def write_parameters(node: canopen.RemoteNode, profile: Profile, values: dict[str, float], *,
                     dry_run: bool = False, store: bool = True, backup_path: str | Path | None = None
                     ) -> WriteResult:
    """Write ``values`` (abstract name -> SI value) to ``node`` through ``profile``.

    ``node.object_dictionary`` must be the profile's EDS.  Returns a
    :class:`WriteResult`; never raises for a drive's refusal.
    """
    supported = [k for k in values if k in profile.entries]
    result = WriteResult(node.id, profile.drive, [], [k for k in values if k not in profile.entries],
                         dry_run=dry_run)
    od = node.object_dictionary
    plan: list[tuple[Entry, ObjectWrite, SdoVariable]] = []
    for name in supported:
        e = profile.entries[name]
        w = ObjectWrite(name, e.index, e.sub, e.unit, new_si=float(values[name]), new_device=e.to_device(values[name]))
        var = od.get_variable(e.index, e.sub)
        low, high = _RANGES.get(var.data_type, (None, None))
        if var.min is not None:
            low = var.min
        if var.max is not None:
            high = var.max
        if (low is not None and w.new_device < low) or (high is not None and w.new_device > high):
            result.objects.append(w)
            result.error = (f"{name} = {values[name]:.6g} {e.unit} is {w.new_device} in device units, outside "
                            f"{e.where()}'s range {low}..{high}; nothing was written")
            return result
        plan.append((e, w, sdo_variable(node, e)))
        result.objects.append(w)
    # 1. backup
    for e, w, var in plan:
        try:
            w.old_device = var.raw
        except SDO_ERRORS as exc:
            result.error = f"reading {w.parameter} ({e.where()}) for the backup failed: {describe_sdo_error(exc)}; nothing was written"
            return result
        w.old_si = e.to_si(w.old_device)
    if backup_path is not None:
        path = Path(backup_path)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps({"node_id": node.id, "drive": profile.drive, "profile": profile.name,
                                    "objects": [{"parameter": w.parameter, "index": w.index, "sub": w.sub,
                                                 "device": w.old_device, "si": w.old_si}
                                                for _, w, _ in plan]}, indent=1))
        result.backup = str(path)
    if dry_run:
        return result
    # 2. write all, 3. read back and compare
    failed = None
    try:
        for e, w, var in plan:
            try:
                var.raw = w.new_device
                w.written = True
            except SDO_ERRORS as exc:
                failed = f"writing {w.parameter} = {w.new_device} to {e.where()} failed: {describe_sdo_error(exc)}"
                break
        if failed is None:
            for e, w, var in plan:
                try:
                    back = var.raw
                except SDO_ERRORS as exc:
                    failed = f"reading back {w.parameter} ({e.where()}) failed: {describe_sdo_error(exc)}"
                    break
                w.verified = _same(e, back, w.new_device)
                if not w.verified:
                    failed = f"{w.parameter} ({e.where()}) reads back {back}, not the {w.new_device} written"
                    break
    except KeyboardInterrupt:
        failed = "interrupted by the user (Ctrl-C)"
    # 4. store only a verified set
    if failed is None and store:
        failed = store_parameters(node, profile, result)
    if failed is not None:
        restore_backup(node, profile, result, failed)
    return result


def store_parameters(node: canopen.RemoteNode, profile: Profile, result: WriteResult) -> str | None:
    """Write 'save' to the profile's store object; the reason when that failed, else None."""
    if profile.save is None:
        result.notes.append(f"{profile.drive} has no store object: the values are not made non-volatile")
        return None
    try:
        node.sdo[profile.save[0]][profile.save[1]].raw = SAVE_SIGNATURE
    except SDO_ERRORS as exc:
        return f"store (0x{profile.save[0]:04X}:{profile.save[1]} 'save') failed: {describe_sdo_error(exc)}"
    result.stored = True
    return None


def restore_backup(node: canopen.RemoteNode, profile: Profile, result: WriteResult, reason: str) -> None:
    """Mark ``result`` failed for ``reason`` and write the backup back to every object it wrote."""
    result.error = reason
    ok = True
    for w in reversed(result.objects):
        if not w.written:
            continue
        e = profile.entries[w.parameter]
        try:
            sdo_variable(node, e).raw = w.old_device
        except SDO_ERRORS as exc:
            ok = False
            result.notes.append(f"restoring {w.parameter} ({e.where()}) failed: {describe_sdo_error(exc)}")
    if not ok:
        result.notes.append("no store was issued, so the drive's stored set is unchanged: "
                            "a power cycle (or NMT reset node) brings it back")
    result.restored = ok
    for w in result.objects:
        w.verified = False


def write_all(nodes: dict[str, canopen.RemoteNode], profile: Profile, values: dict[str, dict[str, float]], *,
              backup_dir: str | Path | None = None) -> dict[str, WriteResult]:
    """Write every axis's ``values`` (axis -> name -> SI) as one transaction over all drives.

    Each drive is written and verified without storing; only when every drive verified is each
    one stored.  Any failure restores the backup of every drive written so far; the axes after
    the failing one are not touched (they have no entry in the result).
    """
    results: dict[str, WriteResult] = {}
    for axis, node in nodes.items():
        backup = Path(backup_dir) / f"{axis}_backup.json" if backup_dir is not None else None
        results[axis] = write_parameters(node, profile, values[axis], store=False, backup_path=backup)
        if not results[axis].ok:
            break
    failed = next(((a, r.error) for a, r in results.items() if not r.ok), None)
    if failed is None:
        for axis, node in nodes.items():
            reason = store_parameters(node, profile, results[axis])
            if reason is not None:
                failed = axis, reason
                restore_backup(node, profile, results[axis], reason)
                break
    if failed is not None:
        for axis, r in results.items():
            if r.ok:
                stored = r.stored
                restore_backup(nodes[axis], profile, r, f"not kept: axis {failed[0]} failed ({failed[1]})")
                if stored and r.restored:          # its new set was stored already: store the backup
                    reason = store_parameters(nodes[axis], profile, r)
                    r.notes.append("the backup was stored again" if reason is None else reason)
                r.stored = False
    return results


def write_drives(nodes: dict[str, canopen.RemoteNode], profile: Profile, values: dict[str, dict[str, float]], *,
                 backup_dir: str | Path | None, dcf_dir: str | Path | None = None,
                 dry_run: bool = False) -> dict[str, WriteResult]:
    """The write step: with ``dry_run`` each drive's old and new values, nothing written;
    else one transaction over every drive (:func:`write_all`, backups in ``backup_dir``)
    and, when every drive verified, each commissioned node exported as a DCF to ``dcf_dir``."""
    require_profile_objects(nodes, profile)
    if dry_run:
        return {a: write_parameters(node, profile, values[a], dry_run=True) for a, node in nodes.items()}
    results = write_all(nodes, profile, values, backup_dir=backup_dir)
    if dcf_dir is not None and transaction_ok(results, nodes):
        for a, r in results.items():
            export_dcf(nodes[a], r, Path(dcf_dir) / f"{a}.dcf")
    return results


def transaction_ok(results: dict[str, WriteResult], nodes) -> bool:
    """Every drive of ``nodes`` has a result, and every result is ok."""
    return len(results) == len(nodes) and all(r.ok for r in results.values())


def results_doc(results: dict[str, WriteResult], nodes) -> dict:
    """write.json / ``write --json``: ``ok`` and every drive's objects."""
    return {"ok": transaction_ok(results, nodes), "axes": {a: r.as_dict() for a, r in results.items()}}


def raise_for_failure(results: dict[str, WriteResult], nodes, backup_dir) -> None:
    """DriveRefused naming the first drive that failed and what was done about it."""
    if transaction_ok(results, nodes):
        return
    failed = next(((a, r) for a, r in results.items() if not r.ok), None)
    if failed is None:
        raise DriveRefused("not every drive was written; nothing was stored")
    a, r = failed
    where = f" ({backup_dir})" if backup_dir is not None else ""
    state = ("every drive written so far was restored from its backup" if all(x.restored or not any(
        w.written for w in x.objects) for x in results.values()) else "NOT every drive could be restored")
    raise DriveRefused(f"axis {a}: {r.error}; {state}{where} and nothing was stored")


def export_dcf(node: canopen.RemoteNode, result: WriteResult, path: str | Path) -> Path:
    """The node's object dictionary as a DCF with the written values as ParameterValue."""
    od = node.object_dictionary
    for w in result.objects:
        var = od.get_variable(w.index, w.sub)
        var.value = w.new_device if result.ok else w.old_device
        var.value_raw = None
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    canopen.export_od(od, str(path), doc_type="dcf")
    return path
