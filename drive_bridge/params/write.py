"""Transactional parameter write: backup, write all, read back and compare, then store.

Nothing is half-written: any failure (SDO abort, time-out, a value out of the
data type's range, a read-back that differs) restores the backup and issues
no store; only when every value is verified is 0x1010 'save' written.  The
result lists every object with its old and new value in SI and device units.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import canopen

from ..cia.dcf import export_dcf
from ..cia.sdo import SDO_ERRORS, address, describe_sdo_error, put_back, sdo_object, snapshot
from ..errors import BusError, DriveRefused, InternalError, UserError, WriteInterrupted
from ..interrupts import deferred, signal_name
from ..outputs import hex_object, stamped, write_json
from .check import GM_FLOOR_DB, PM_FLOOR_DEG, ValueRefused, check_set, gate
from .profile import Entry, Profile
from .read import motor_data, require_profile_objects, sdo_variable

log = logging.getLogger(__name__)

SAVE_SIGNATURE = 0x65766173  # "save"


@dataclass
class ObjectWrite:
    """One object of a write, as far as it went.

    Parameters
    ----------
    parameter : str
        The abstract parameter (J, KpS, ...).
    index, sub : int
        Its object on the drive.
    unit : str
        The parameter's SI unit.
    old_si, new_si : float, optional
        The value before (as backed up) and the value to write, SI.
    old_device, new_device : float or int, optional
        The same in the object's units.
    attempted : bool
        A write was sent (its answer may have been lost).
    written : bool
        The drive confirmed the write.
    verified : bool
        Read back equal to what was written (and still in force).
    """

    parameter: str
    index: int
    sub: int
    unit: str
    old_si: float | None = None
    new_si: float | None = None
    old_device: float | int | None = None
    new_device: float | int | None = None
    attempted: bool = False
    written: bool = False
    verified: bool = False


#: what a drive's RAM or its stored (non-volatile) set holds after a transaction
NEW, BACKUP, UNCHANGED, UNKNOWN = "new", "backup", "unchanged", "unknown"
#: what a store makes permanent besides the objects written (CiA 301 0x1010 sub-indices)
STORE_SCOPE = {
    1: "every parameter the drive held in RAM (0x1010:1), not only the objects written: bring-up's "
    "PDO mapping and communication parameters, heartbeat consumer, limits and stop behaviour with them",
    2: "the communication parameters (0x1010:2)",
    3: "the application parameters (0x1010:3)",
}
#: what a restore after a store puts back: with bring-up's snapshot of what it overwrote, everything;
#: without it (for the reason given), the objects written only
RESTORE_ALL = (
    "the objects written, and every object bring-up overwrote (PDO mapping and communication parameters, "
    "heartbeat, limits, stop behaviour) as the drive held it when bring-up found it -- its stored set, "
    "unless something changed it since the drive was powered on: stored that way, then bring-up's values "
    "set again in RAM for the rest of the run"
)
RESTORE_WRITTEN = (
    "only the objects written: {why}, so the values the store made permanent for bring-up's PDO "
    "mapping, heartbeat, limits and stop behaviour (as a bring-up left them in RAM) stay stored"
)
NO_BRING_UP = "this write did not bring the drives up"


@dataclass
class WriteResult:
    """What happened on one drive: never more than was read back.

    Parameters
    ----------
    node_id : int or None
        The drive's node id.
    drive : str
        The drive model.
    objects : list of ObjectWrite
        Each object of the set, as far as it went.
    unsupported : list of str
        Parameters of the set the drive's profile has no object for.
    dry_run : bool
        Only the backup phase ran.
    stored : bool
        The new set was stored (made permanent).
    restored : bool
        The backup was put back.
    error : str, optional
        What failed on this drive; None: ``ok``, every object written and verified (and stored
        if asked).
    backup : str, optional
        Where the backup was written.
    notes : list of str
        What else happened, in words.
    ram, stored_set : {"new", "backup", "unchanged", "unknown"}
        What the drive is known to hold in RAM and in its stored set (``backup``: as before;
        ``unchanged``: never touched; ``unknown``: could not be read back or confirmed).
    interrupted : str, optional
        The signal that cut the transaction short (Ctrl-C, SIGTERM, SIGHUP).
    caused : bool
        This drive's failure ended the transaction.
    store_scope : str, optional
        What a store sent to this drive made permanent besides the objects written (None: no store
        sent).
    restore_covers : str, optional
        What a restore after it puts back.
    """

    node_id: int | None
    drive: str
    objects: list[ObjectWrite]
    unsupported: list[str]
    dry_run: bool = False
    stored: bool = False
    restored: bool = False
    error: str | None = None
    backup: str | None = None
    notes: list[str] = field(default_factory=list)
    ram: str = UNCHANGED
    stored_set: str = UNCHANGED
    interrupted: str | None = None
    caused: bool = False
    store_scope: str | None = None
    restore_covers: str | None = None

    def holds(self) -> str:
        """What the drive is known to hold.

        Returns
        -------
        str
            Its RAM and its stored set, in words.
        """
        ram = {
            NEW: "new values in RAM",
            BACKUP: "restored (read back)",
            UNCHANGED: "untouched",
            UNKNOWN: "RAM UNKNOWN (could not be read back)",
        }[self.ram]
        return f"{ram}, stored set {self.stored_set}"

    @property
    def ok(self) -> bool:
        """Every object written and verified (and stored if asked): no error."""
        return self.error is None

    def as_dict(self) -> dict:
        """One drive as write.json holds it.

        Returns
        -------
        dict
            Every field and ``ok``; each object's address as ``"0x2000:3"``.
        """
        d = asdict(self)
        d["objects"] = [
            {"parameter": o.pop("parameter"), "object": hex_object(o.pop("index"), o.pop("sub")), **o}
            for o in d["objects"]
        ]
        d["ok"] = self.ok
        return d


def _same(entry: Entry, a: Any, b: Any) -> bool:
    return entry.held(a) == entry.held(b)


class _Failed(Exception):
    """A read-back that differs from what was written."""


def _describe(exc: BaseException, phase: str, w: ObjectWrite | None, entry: Entry | None) -> str:
    what = "" if w is None or entry is None else f" {w.parameter} ({entry.where()})"
    if isinstance(exc, KeyboardInterrupt):
        return f"interrupted by {signal_name(exc)} during the {phase} phase"
    if isinstance(exc, _Failed):
        return str(exc)
    doing = {
        "backup": f"reading{what} for the backup",
        "write": f"writing{what} = {w.new_device if w else ''}",
        "verify": f"reading back{what}",
        "store": "storing (0x1010 'save')",
    }[phase]
    if isinstance(exc, SDO_ERRORS):
        return f"{doing} failed: {describe_sdo_error(exc)}"
    return f"{doing} failed: {type(exc).__name__}: {exc}"


def bind_axes(
    profile: Profile, axes: Iterable[str], torque_constants: dict[str, float | None] | None
) -> dict[str, Profile]:
    """A drive profile bound to each axis's motor.

    Parameters
    ----------
    profile : Profile
        The drive profile.
    axes : iterable of str
        The axes.
    torque_constants : dict of str to float or None, optional
        Per axis, its motor's torque constant [Nm/A], where the drive holds values in current.

    Returns
    -------
    dict of str to Profile
        Per axis, :meth:`~.profile.Profile.bind`.

    Raises
    ------
    UserError
        A profile that needs a torque constant an axis does not have.
    """
    return {a: profile.bind((torque_constants or {}).get(a), a) for a in axes}


def plan_writes(
    nodes: dict[str, canopen.RemoteNode],
    profiles: dict[str, Profile],
    values: dict[str, dict[str, float]],
    *,
    check: bool = True,
    dry_run: bool = False,
) -> dict[str, WriteResult]:
    """The objects each drive will get, checked before anything is written.

    Parameters
    ----------
    nodes : dict of str to canopen.RemoteNode
        The drives, by axis.
    profiles : dict of str to Profile
        Their profiles, bound to their motors.
    values : dict of str to dict
        Per axis, the set in the cascade's terms (as tune gives them, SI), turned into the
        parameters of the controller its profile declares.
    check : bool
        Check every value first (:func:`~drive_bridge.params.check.check_set`).
    dry_run : bool
        Mark the results as a dry run.

    Returns
    -------
    dict of str to WriteResult
        Per axis, its objects with the values to write (nothing written yet).

    Raises
    ------
    ValueRefused
        Every problem of every drive, named, before anything is written.
    """
    problems = []
    results = {}
    for axis, node in nodes.items():
        profile = profiles[axis]
        try:
            vals = profile.drive_values(values[axis])
        except UserError as exc:
            problems.append(f"axis {axis}: {exc}")
            continue
        if check:
            problems += [f"axis {axis}: {p}" for p in check_set(profile, node.object_dictionary, vals)]
        objects = [
            ObjectWrite(
                k,
                profile.entries[k].index,
                profile.entries[k].sub,
                profile.entries[k].unit,
                new_si=float(v),
                new_device=None if problems else profile.entries[k].to_device(v),
            )
            for k, v in vals.items()
            if k in profile.entries
        ]
        results[axis] = WriteResult(
            node.id, profile.drive, objects, [k for k in vals if k not in profile.entries], dry_run=dry_run
        )
    if problems:
        raise ValueRefused("refused before anything was written: " + "; ".join(problems))
    return results


def write_all(
    nodes: dict[str, canopen.RemoteNode],
    profile: Profile,
    values: dict[str, dict[str, float]],
    *,
    backup_dir: str | Path | None = None,
    store: bool = True,
    dry_run: bool = False,
    check: bool = True,
    settings_before: dict[str, dict[str, int]] | None = None,
    torque_constants: dict[str, float | None] | None = None,
) -> dict[str, WriteResult]:
    """Write every axis's ``values`` (axis -> name -> SI) as one transaction over all drives.

    Every value is checked before anything is written (``check``).  Then: backup (read every
    object), write every drive, read every value back and compare, and only then store on each
    drive (``store``).  Any failure -- an SDO abort, a lost answer, a value the data type cannot
    hold, a read-back that differs, an exception, Ctrl-C, SIGTERM or SIGHUP, in any phase --
    restores the backup on every drive that was written, reads it back and compares, and
    stores it again where the new set had been stored -- with ``settings_before`` (per axis what
    bring-up overwrote, :attr:`~drive_bridge.master.bringup.AxisLink.before`) put back for that
    store, so the stored set is the one the drive had.

    Parameters
    ----------
    nodes : dict of str to canopen.RemoteNode
        The drives, by axis.
    profile : Profile
        Their drive profile.
    values : dict of str to dict
        Per axis, name -> value, SI.
    backup_dir : str or Path, optional
        Where each drive's backup is written (a DCF per drive).
    store : bool
        Store the new set on each drive once every drive holds it.
    dry_run : bool
        The backup phase only.
    check : bool
        Check every value before anything is written.
    settings_before : dict of str to dict, optional
        Per axis, what bring-up overwrote (:attr:`~drive_bridge.master.bringup.AxisLink.before`).
    torque_constants : dict of str to float or None, optional
        Per axis [Nm/A], where the drive holds values in current.

    Returns
    -------
    dict of str to WriteResult
        Per axis, what happened and what the drive is known to hold.

    Raises
    ------
    ValueRefused
        A value refused before anything was written.
    """
    profiles = bind_axes(profile, nodes, torque_constants)
    results = plan_writes(nodes, profiles, values, check=check, dry_run=dry_run)
    _Transaction(nodes, profiles, results, _backup_paths(nodes, backup_dir), settings_before).run(
        store, dry_run
    )
    return results


def _backup_paths(nodes: Iterable[str], backup_dir: str | Path | None) -> dict[str, Path | None]:
    return {a: None if backup_dir is None else Path(backup_dir) / f"{a}_backup.json" for a in nodes}


def write_parameters(
    node: canopen.RemoteNode,
    profile: Profile,
    values: dict[str, float],
    *,
    dry_run: bool = False,
    store: bool = True,
    backup_path: str | Path | None = None,
    check: bool = True,
) -> WriteResult:
    """:func:`write_all` for one drive.

    Parameters
    ----------
    node : canopen.RemoteNode
        The drive.
    profile : Profile
        Its profile, bound to its motor (:meth:`~.profile.Profile.bind`).
    values : dict of str to float
        Name -> value, SI.
    dry_run : bool
        The backup phase only.
    store : bool
        Store the new set once it is verified.
    backup_path : str or Path, optional
        Where its backup goes.
    check : bool
        Check every value before anything is written.

    Returns
    -------
    WriteResult
        What happened and what the drive is known to hold.

    Raises
    ------
    ValueRefused
        A value refused before anything was written.
    """
    results = plan_writes({"": node}, {"": profile}, {"": values}, check=check, dry_run=dry_run)
    _Transaction(
        {"": node}, {"": profile}, results, {"": None if backup_path is None else Path(backup_path)}
    ).run(store, dry_run)
    return results[""]


class _Transaction:
    def __init__(
        self,
        nodes: dict[str, canopen.RemoteNode],
        profiles: dict[str, Profile],
        results: dict[str, WriteResult],
        backup_paths: dict[str, Path | None],
        settings_before: dict[str, dict[str, int]] | None = None,
        strayed: Callable[[], str | None] | None = None,
    ):
        self.nodes, self.profiles, self.results = nodes, profiles, results
        self.strayed = strayed  # after the read-back: an axis held powered that the new set let go
        self.profile = next(iter(profiles.values()))  # the drive model's (name, store object)
        self.backup_paths = backup_paths
        self.settings_before = settings_before or {}
        self.store_state: dict[str, str] = dict.fromkeys(results, UNCHANGED)
        self.interrupted_in_restore: str | None = None  # a KeyboardInterrupt the restore finished despite

    def _get(self, axis: str, w: ObjectWrite) -> int | float:
        """``w``'s object as the drive holds it [device units]."""
        value = sdo_variable(self.nodes[axis], self._entry(axis, w)).raw
        if not isinstance(value, (int, float)):
            raise DriveRefused(
                f"axis {axis}: {w.parameter} ({self._entry(axis, w).where()}) reads {value!r}, not a number"
            )
        return value

    def _set(self, axis: str, w: ObjectWrite, value: int | float | None) -> None:
        """Download ``value`` [device units] to ``w``'s object."""
        if value is None:
            raise InternalError(f"axis {axis}: {w.parameter} has no device value to write")
        sdo_variable(self.nodes[axis], self._entry(axis, w)).raw = value

    def _entry(self, axis: str, w: ObjectWrite) -> Entry:
        return self.profiles[axis].entries[w.parameter]

    def run(self, store: bool, dry_run: bool) -> None:
        phase = "backup"
        where: tuple[str | None, ObjectWrite | None] = (None, None)  # the axis and object at work
        try:
            for a, r in self.results.items():
                for w in r.objects:
                    where = (a, w)
                    w.old_device = self._get(a, w)
                    w.old_si = self._entry(a, w).to_si(w.old_device)
                self._save_backup(a, r)
            if dry_run:
                return
            phase = "write"
            for a, r in self.results.items():
                for w in r.objects:
                    where = (a, w)
                    w.attempted = True
                    self._set(a, w, w.new_device)
                    w.written = True
            phase = "verify"
            for a, r in self.results.items():
                for w in r.objects:
                    where = (a, w)
                    back = self._get(a, w)
                    w.verified = _same(self._entry(a, w), back, w.new_device)
                    if not w.verified:
                        raise _Failed(
                            f"{w.parameter} ({self._entry(a, w).where()}) reads back "
                            f"{back}, not the {w.new_device} written"
                        )
            problem = self.strayed() if self.strayed is not None else None
            if problem is not None:
                raise _Failed(problem)
            phase = "store"
            for a, r in self.results.items():
                where = (a, None)
                if store and r.objects:  # nothing written: nothing to make non-volatile
                    self._store(a, r)
            for r in self.results.values():
                r.ram = NEW
        except (Exception, KeyboardInterrupt) as exc:
            axis, at = where
            reason = _describe(exc, phase, at, None if at is None or axis is None else self._entry(axis, at))
            if isinstance(exc, KeyboardInterrupt):
                for r in self.results.values():
                    r.interrupted = signal_name(exc)
            if phase == "backup":
                for a, r in self.results.items():
                    r.caused = a == axis
                    r.error = (
                        reason + "; nothing was written"
                        if a == axis
                        else f"not written: axis {axis} failed ({reason})"
                    )
                return
            with deferred(raise_after=False) as held:
                self._restore(axis, reason)
            late = held["signal"] or self.interrupted_in_restore
            if late:
                for r in self.results.values():
                    r.interrupted = r.interrupted or late

    def _save_backup(self, axis: str, r: WriteResult) -> None:
        path = self.backup_paths[axis]
        if path is None:
            return
        write_json(
            path,
            {
                "node_id": r.node_id,
                "drive": self.profile.drive,
                "profile": self.profile.name,
                "objects": [
                    {
                        "parameter": w.parameter,
                        "index": w.index,
                        "sub": w.sub,
                        "device": w.old_device,
                        "si": w.old_si,
                    }
                    for w in r.objects
                ],
                "settings_before_bring_up": self.settings_before.get(axis),
            },
            exact=True,
        )
        r.backup = str(path)

    def _store(self, axis: str, r: WriteResult) -> None:
        save = self.profile.save
        if save is None:
            r.notes.append(f"{self.profile.drive} has no store object: the values are not made non-volatile")
            return
        log.info("axis %s: storing (0x%04X:%d 'save')", axis, *save)
        self.store_state[axis] = UNKNOWN  # sent: until it is confirmed, nobody knows
        r.store_scope = STORE_SCOPE.get(save[1], f"what 0x{save[0]:04X}:{save[1]} stores")
        r.restore_covers = (
            RESTORE_ALL if self.settings_before.get(axis) else RESTORE_WRITTEN.format(why=NO_BRING_UP)
        )
        self.nodes[axis].sdo[save[0]][save[1]].raw = SAVE_SIGNATURE
        self.store_state[axis] = NEW
        r.stored, r.stored_set = True, NEW

    def _restore(self, failed_axis: str | None, reason: str) -> None:
        """Write the backup to every drive written so far, read it back, and store it again where
        a store of the new set was sent; record what each drive is known to hold."""
        for a, r in self.results.items():
            r.error = reason if a == failed_axis else f"not kept: axis {failed_axis} failed ({reason})"
            r.caused = a == failed_axis
            touched = [w for w in r.objects if w.attempted]
            for w in r.objects:
                w.verified = False
            if not touched and self.store_state[a] == UNCHANGED:
                r.ram = UNCHANGED
                continue
            for w in reversed(touched):
                try:
                    self._restore_object(a, w)
                except (Exception, KeyboardInterrupt) as exc:
                    self._note_interrupt(exc)
                    entry = self._entry(a, w)
                    r.notes.append(f"restoring {w.parameter} failed: {_describe(exc, 'write', w, entry)}")
            back_ok = True
            for w in touched:
                try:
                    back = self._get(a, w)
                except (Exception, KeyboardInterrupt) as exc:
                    self._note_interrupt(exc)
                    back_ok = False
                    why = describe_sdo_error(exc) if isinstance(exc, SDO_ERRORS) else type(exc).__name__
                    r.notes.append(f"{w.parameter} could not be read back after restoring ({why})")
                    continue
                if not _same(self._entry(a, w), back, w.old_device):
                    back_ok = False
                    r.notes.append(
                        f"{w.parameter} reads {back} after restoring, not its backup {w.old_device}"
                    )
            r.ram = BACKUP if back_ok else UNKNOWN
            r.restored = back_ok
            self._restore_stored_set(a, r)

    @contextmanager
    def _as_before_bring_up(self, axis: str, r: WriteResult) -> Iterator[None]:
        """Around the store of the backup: what bring-up overwrote as the drive held it before, then
        bring-up's values again in RAM (the run still streams with them).  A put-back that fails is
        noted and the store goes on (the backup of the objects written still stands)."""
        before = self.settings_before.get(axis)
        if not before:
            yield
            return
        node = self.nodes[axis]
        live = snapshot(node, axis, [address(k) for k in before])
        try:
            put_back(node, axis, before)
        except (Exception, KeyboardInterrupt) as exc:
            self._note_interrupt(exc)
            r.restore_covers = RESTORE_WRITTEN.format(why=f"putting bring-up's settings back failed ({exc})")
            r.notes.append(
                f"bring-up's settings could not be put back as they were before it ({exc}): they stay "
                f"stored as bring-up set them"
            )
        else:
            r.notes.append(
                f"the {len(before)} objects bring-up overwrote were stored as the drive held them before it"
            )
        yield
        try:
            put_back(node, axis, live)
        except (Exception, KeyboardInterrupt) as exc:
            self._note_interrupt(exc)
            r.notes.append(
                f"bring-up's settings could not be set again in RAM ({exc}): the drive runs with its "
                f"settings from before bring-up until it is brought up again"
            )

    def _restore_object(self, axis: str, w: ObjectWrite) -> None:
        """Write one object's backup; an interrupt is not the drive's answer, so that object is
        tried once more before the restore goes on."""
        try:
            self._set(axis, w, w.old_device)
        except KeyboardInterrupt as exc:
            self._note_interrupt(exc)
            self._set(axis, w, w.old_device)

    def _note_interrupt(self, exc: BaseException) -> None:
        """The restore goes on through an interrupt (it is what makes the drive safe); remember it."""
        if isinstance(exc, KeyboardInterrupt):
            self.interrupted_in_restore = self.interrupted_in_restore or signal_name(exc)

    def _restore_stored_set(self, axis: str, r: WriteResult) -> None:
        state = self.store_state[axis]
        r.stored = False
        if state == UNCHANGED:
            r.stored_set = UNCHANGED
            r.notes.append(
                "no store was sent to this drive: its stored set is the one it had "
                "(a power cycle or NMT reset node brings it back)"
            )
            return
        if r.ram != BACKUP:
            r.stored_set = state
            r.notes.append(
                "its RAM could not be confirmed as the backup, so it was not stored again: its stored "
                + (
                    "set holds the new values"
                    if state == NEW
                    else "set is unknown (a store was sent without an answer)"
                )
            )
            return
        try:
            save = self.profile.save
            if save is None:
                raise DriveRefused(
                    f"the {self.profile.drive} profile names no object that stores the parameters"
                )
            with self._as_before_bring_up(axis, r):
                sdo_object(self.nodes[axis], *save).raw = SAVE_SIGNATURE
            r.stored_set = BACKUP
            r.notes.append("the backup was stored again")
        except (Exception, KeyboardInterrupt) as exc:
            self._note_interrupt(exc)
            lost = not isinstance(exc, canopen.SdoAbortedError)
            r.stored_set = UNKNOWN if lost or state == UNKNOWN else NEW
            r.notes.append(
                f"storing the backup again failed ({_describe(exc, 'store', None, None)}): its stored set "
                + ("is unknown" if r.stored_set == UNKNOWN else "holds the new values")
            )


@dataclass
class WriteOutcome:
    """The write step's outcome (:func:`write_drives`).

    Parameters
    ----------
    results : dict of str to WriteResult
        Per drive: what was written and read back, stored, or rolled back, and why.
    margins : dict of str to dict
        Per axis, the loop margins [°, dB] of the gains written, on the model they were designed
        for.
    forced : list of str
        The checks ``force`` overrode.
    axes : list of str
        The axes asked for.
    unverified_scales : list of str
        Values written through a profile scale without a documented source (``"KpS (0x3210:3)"``).
    """

    results: dict[str, WriteResult]
    margins: dict[str, dict]
    forced: list[str]
    axes: list[str]
    unverified_scales: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        """Whether every drive asked for has a result and none of them an error."""
        return len(self.results) == len(self.axes) and all(r.ok for r in self.results.values())

    def as_dict(self) -> dict:
        """The outcome as write.json and ``write --json`` hold it.

        Returns
        -------
        dict
            ``ok``, ``forced``, ``margins``, ``unverified_scales`` and per axis its result
            (schema ``write``, stamped with the tool's version).
        """
        return stamped(
            "write",
            {
                "ok": self.ok,
                "forced": self.forced,
                "margins": self.margins,
                "unverified_scales": self.unverified_scales,
                "axes": {a: r.as_dict() for a, r in self.results.items()},
            },
        )


def write_drives(
    nodes: dict[str, canopen.RemoteNode],
    profile: Profile,
    values: dict[str, dict[str, float]],
    *,
    backup_dir: str | Path | None,
    dcf_dir: str | Path | None = None,
    dry_run: bool = False,
    inductance: dict[str, float | None] | None = None,
    force: bool = False,
    pm_floor: float = PM_FLOOR_DEG,
    gm_floor: float = GM_FLOOR_DB,
    allow_unverified_scales: bool = False,
    bitrate: int = 1_000_000,
    settings_before: dict[str, dict[str, int]] | None = None,
    frf: dict | None = None,
    torque_constants: dict[str, float | None] | None = None,
    strayed: Callable[[], str | None] | None = None,
) -> WriteOutcome:
    """The write step: every value checked, then one transaction over every drive.

    Every value is checked against its physical range, the drive's limits and the EDS; each
    drive's gains against the model in its set (J, c1) and, where measured, its response (the
    margins of the values as written, the worse of the two). Then one transaction over every
    drive (:func:`write_all`): written, stored, read back; on any failure every drive is put
    back to its backup. Nothing is half-written.

    Parameters
    ----------
    nodes : dict of str to canopen.RemoteNode
        The drives by axis, brought up.
    profile : Profile
        The drive profile: which object holds each parameter, in which unit.
    values : dict of str to dict of str to float
        Per axis the parameters to write (J [kg·m²], c0 [Nm], c1 [Nm·s/rad], KpP [1/s], FwF [1],
        KpS [Nm·s/rad], KiS [1/s], ...), SI, motor side.
    backup_dir : str or Path or None
        Where each drive's values before the write are kept (None: not kept).
    dcf_dir : str or Path, optional
        Where each commissioned node is exported as a DCF once every drive verified.
    dry_run : bool
        Check and show each drive's old and new values; nothing is written.
    inductance : dict of str to float, optional
        Per axis the motor inductance [H] for the margin check; default the motor data objects
        the profile names.
    force : bool
        Write a gain set whose margins are below the floor (recorded as forced).
    pm_floor, gm_floor : float
        The margin floor [°], [dB] a gain set must keep.
    allow_unverified_scales : bool
        Write through profile scales without a documented source (a dry run shows them).
    bitrate : int
        The bus bitrate [bit/s] written into the exported DCFs.
    settings_before : dict, optional
        What bring-up overwrote, per axis, put back with a failed write.
    frf : dict of str to Frf, optional
        Per axis the response measured through the drive: the gains keep their margins on it too.
    torque_constants : dict of str to float, optional
        Per axis [Nm/A], where the drive holds values in current.
    strayed : callable, optional
        Asked once every value reads back, before anything is stored: an axis held powered that
        the new set let go of, in words (:meth:`drive_bridge.master.hold.HeldAxes.strayed`); one
        it names puts every drive back to its backup.

    Returns
    -------
    WriteOutcome
        Per axis what was written, stored and read back, the margins, the sets forced.

    Raises
    ------
    ValueRefused
        A value out of its range or a gain set below the margin floor, before anything is written.
    """
    require_profile_objects(nodes, profile)
    profiles = bind_axes(profile, nodes, torque_constants)
    results = plan_writes(nodes, profiles, values, dry_run=dry_run)  # every value first: ValueRefused
    L = {}
    for a, node in nodes.items():
        L[a] = (inductance or {}).get(a)
        if L[a] is None and profile.motor is not None:  # the drive reports its motor data
            try:
                L[a] = motor_data(node, profile)[1]
            except BusError:
                L[a] = None
    checked = gate(
        profiles,
        values,
        L,
        force=force,
        pm_floor=pm_floor,
        gm_floor=gm_floor,
        allow_unverified_scales=allow_unverified_scales,
        dry_run=dry_run,
        frf=frf,
    )
    _Transaction(nodes, profiles, results, _backup_paths(nodes, backup_dir), settings_before, strayed).run(
        True, dry_run
    )
    outcome = WriteOutcome(results, checked.margins, checked.forced, list(nodes), checked.unverified)
    if dcf_dir is not None and not dry_run and outcome.ok:
        for a in results:
            export_dcf(nodes[a], Path(dcf_dir) / f"{a}.dcf", bitrate)
    return outcome


def raise_for_failure(outcome: WriteOutcome, backup_dir: str | Path | None) -> None:
    """The error a failed write ends with: what failed, and per drive what it holds now.

    Parameters
    ----------
    outcome : WriteOutcome
        The write step's outcome (nothing is raised where it is ``ok``).
    backup_dir : str or Path, optional
        Where the backups are, said in the message.

    Raises
    ------
    WriteInterrupted
        A signal cut the transaction short.
    BusError
        A dry run that could not read a drive.
    DriveRefused
        A drive refused or lost the set.
    """
    if outcome.ok:
        return
    axis = next((a for a, r in outcome.results.items() if r.caused), None)
    where = f"; backups in {backup_dir}" if backup_dir is not None else ""
    states = "; ".join(f"{a}: {r.holds()}" for a, r in outcome.results.items())
    message = (
        f"axis {axis}: {outcome.results[axis].error}" if axis else "not every drive was written"
    ) + f" ({states}){where}"
    failed = outcome.results.get(axis) if axis else None
    interrupted = next((r.interrupted for r in outcome.results.values() if r.interrupted), None)
    if interrupted:
        raise WriteInterrupted(message)
    if failed is not None and failed.dry_run:
        raise BusError(f"dry run: {message}")
    raise DriveRefused(message)
