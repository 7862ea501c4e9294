"""Reading a drive: its parameters in SI through the drive profile, its motor data, and the
state bring-up records before commissioning (the set a commissioning can be compared with)."""

from __future__ import annotations

from collections.abc import Collection

import canopen
from canopen.sdo import SdoVariable

from ..cia.sdo import SDO_ERRORS, describe_sdo_error, sdo_object
from ..errors import BusError, UserError
from ..outputs import identity_hex
from .profile import SELECT, Entry, Profile


def sdo_variable(node: canopen.RemoteNode, entry: Entry) -> SdoVariable:
    """The SDO accessor of a parameter's object on a drive (canopen's own lookup).

    Parameters
    ----------
    node : canopen.RemoteNode
        The drive.
    entry : Entry
        The parameter's object.

    Returns
    -------
    SdoVariable
        canopen's accessor (``.raw`` reads and writes it).
    """
    return sdo_object(node, entry.index, entry.sub)


def read_parameters(
    node: canopen.RemoteNode, profile: Profile, names: Collection[str] | None = None
) -> dict[str, float]:
    """The drive's current values [SI] of ``names`` in the cascade's terms (default: every
    parameter of ``profile``; names the profile has no object for are left out): its controller's
    parameters read and turned into them (``profile`` bound to the axis's motor).  Where the
    profile has a select object, its value too (``gain_objects``), and a drive not on the
    profile's gain objects is read through the profile that runs there: what the drive runs.

    Parameters
    ----------
    node : canopen.RemoteNode
        The drive.
    profile : Profile
        Its profile, bound to the axis's motor.
    names : collection of str, optional
        The parameters (default: every parameter of the profile).

    Returns
    -------
    dict of str to float
        Name -> value, SI.

    Raises
    ------
    BusError
        The drive does not answer or refuses a read, naming the object.
    """
    out = {}
    if profile.select is not None:  # a drive not on the profile's gain objects runs others
        entry = profile.select[0]
        out[entry.parameter] = selected = _read(node, entry)
        if selected != profile.select[1] and (otherwise := profile.otherwise()) is not None:
            profile = otherwise
    for name in profile.entries if names is None else profile.controller.drive_names(names):
        if name in profile.entries:
            out[name] = _read(node, profile.entries[name])
    out = profile.controller.from_drive(out)
    return out if names is None else {k: v for k, v in out.items() if k in names or k == SELECT}


def _read(node: canopen.RemoteNode, entry: Entry) -> float:
    """``entry``'s value on ``node`` [SI]; BusError naming the object when the drive does not
    answer or refuses."""
    try:
        return entry.to_si(float(sdo_variable(node, entry).raw))
    except SDO_ERRORS as exc:
        raise BusError(
            f"node {node.id}: reading {entry.parameter} ({entry.where()}) failed: {describe_sdo_error(exc)}"
        ) from exc


def motor_data(
    node: canopen.RemoteNode, profile: Profile, R: float | None = None, L: float | None = None
) -> tuple[float, float]:
    """The motor's winding resistance and inductance.

    Parameters
    ----------
    node : canopen.RemoteNode
        The drive.
    profile : Profile
        Its profile (``motor``: the objects that hold them).
    R : float, optional
        [Ω], given.
    L : float, optional
        [H], given.

    Returns
    -------
    R, L : float
        [Ω], [H]: as given, else read from the drive.

    Raises
    ------
    BusError
        Reading them failed.
    UserError
        Not given, and the profile names no objects for them.
    """
    if R and L:
        return R, L
    if profile.motor is not None:
        try:
            R, L = (float(sdo_object(node, *profile.motor[k]).raw) for k in ("R", "L"))
            return R, L
        except SDO_ERRORS as exc:
            raise BusError(
                f"node {node.id}: reading its motor data failed: {describe_sdo_error(exc)}"
            ) from exc
    raise UserError(
        f"node {node.id}: the {profile.drive} profile names no motor data objects; give the motor's "
        f"winding resistance and inductance as motor: {{R_ohm: ..., L_H: ...}} of the node in the bus "
        f"configuration, or --motor-R and --motor-L"
    )


def require_profile_objects(nodes: dict[str, canopen.RemoteNode], profile: Profile) -> None:
    """Check that every drive's EDS/DCF holds every object of the profile.

    Parameters
    ----------
    nodes : dict of str to canopen.RemoteNode
        The drives, by axis.
    profile : Profile
        The profile.

    Raises
    ------
    UserError
        Naming the axis and the object (a wrong profile).
    """
    for a, node in nodes.items():
        missing = [
            e.where()
            for e in profile.entries.values()
            if node.object_dictionary.get_variable(e.index, e.sub) is None
        ]
        if missing:
            raise UserError(
                f"axis {a}: the EDS/DCF of node {node.id} has no object {', '.join(missing)} of the "
                f"drive profile {profile.path}; choose the profile of this drive (--profile)"
            )


def drive_state(axes: dict, profile: Profile, motor: tuple[float, float] | None = None) -> dict[str, dict]:
    """Per brought-up axis (:class:`~drive_bridge.master.bringup.AxisLink`): node id, identity,
    motor R [Ω] / L [H] (``motor``, else the node's bus configuration, else the drive's objects) and
    every parameter of ``profile`` as the drive holds it now [SI].

    Parameters
    ----------
    axes : dict
        The brought-up axes.
    profile : Profile
        Their drive's profile.
    motor : (float, float), optional
        R [Ω], L [H] for every axis.

    Returns
    -------
    dict of str to dict
        Per axis: ``node_id``, ``identity``, ``motor`` and ``parameters_before``.

    Raises
    ------
    UserError
        A drive whose EDS/DCF lacks an object of the profile (a wrong profile).
    """
    require_profile_objects({a: ax.node for a, ax in axes.items()}, profile)
    out = {}
    for a, ax in axes.items():
        R, L = motor_data(ax.node, profile, *(motor or ax.cfg.motor or (None, None)))
        out[a] = {
            "node_id": ax.cfg.node_id,
            "identity": identity_hex(ax.identity),
            "motor": {"R": R, "L": L},
            "parameters_before": read_parameters(ax.node, profile.for_axis(ax)),
        }
    return out
