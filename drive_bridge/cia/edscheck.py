"""What in an EDS/DCF file is not CiA 306, and what drive-bridge can do with the drive it describes.

drive-bridge reads vendor files as they are (:func:`~drive_bridge.cia.od.load_od`); this check says
what other tools would stumble over: keys CiA 306 does not have, REAL32/REAL64 values written as
decimals (CiA 306 tools such as Lely's read them as IEEE 754 bit patterns), values that do not
parse as their data type, ``$NODEID`` in another form than ``$NODEID+value``, objects listed but
not described (or the reverse), mandatory objects missing, text that is not UTF-8.  Where Lely's
``dcf-tools`` are installed their linter runs too, and its findings are listed beside ours.
"""

from __future__ import annotations

import configparser
import re
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import canopen
from canopen.objectdictionary import datatypes

from ..errors import ConfigError
from .od import default, load_od
from .setpoint import describe_modes

OBJECT_KEYS = {
    k.lower()
    for k in (
        "ParameterName",
        "ObjectType",
        "DataType",
        "AccessType",
        "DefaultValue",
        "PDOMapping",
        "LowLimit",
        "HighLimit",
        "SubNumber",
        "CompactSubObj",
        "ObjFlags",
        "ParameterValue",
        "Denotation",
        "UploadFile",
        "DownloadFile",
        "ParameterRefd",
    )
}
LISTS = ("MandatoryObjects", "OptionalObjects", "ManufacturerObjects")
MANDATORY = (0x1000, 0x1001, 0x1018)
OBJECT = re.compile(r"^([0-9A-F]{4})(sub([0-9A-F]+))?$", re.IGNORECASE)
NODEID = re.compile(r"^\$NODEID\s*\+\s*(0x[0-9A-F]+|[0-9]+)$", re.IGNORECASE)
VALUE_KEYS = ("DefaultValue", "ParameterValue", "LowLimit", "HighLimit")
INTEGER_TYPES = {*datatypes.INTEGER_TYPES, datatypes.BOOLEAN}
#: what drive-bridge reads or writes, by the role it plays
ROLES = {
    "controlword": [0x6040],
    "statusword": [0x6041],
    "modes of operation": [0x6060, 0x6061],
    "position actual": [0x6064],
    "velocity actual": [0x606C],
    "torque or current actual": [0x6077, 0x6078],
    "store parameters": [0x1010],
}


@dataclass
class Report:
    """What :func:`check` found in an EDS/DCF.

    Parameters
    ----------
    path : Path
        The file.
    findings : list of str
        What is not CiA 306.
    lely : list of str, optional
        Lely's dcfchk lint; None: not installed.
    drive : list of str
        What drive-bridge finds it can use.
    """

    path: Path
    findings: list[str] = field(default_factory=list)
    lely: list[str] | None = None
    drive: list[str] = field(default_factory=list)

    @property
    def standard(self) -> bool:
        """Nothing found that is not CiA 306 (by this check and by Lely's, where installed)."""
        return not self.findings and not self.lely

    def as_dict(self) -> dict:
        """The report as ``check-eds --json`` gives it.

        Returns
        -------
        dict
            ``path``, ``standard``, ``findings``, ``lely``, ``drive``.
        """
        return {
            "path": str(self.path),
            "standard": self.standard,
            "findings": self.findings,
            "lely": self.lely,
            "drive": self.drive,
        }


class _CaseKeeping(configparser.RawConfigParser):
    """An INI parser that keeps the keys' case (``DefaultValue``, ``ParameterName``), as CiA 306 spells them."""

    def optionxform(self, optionstr: str) -> str:
        return optionstr


def check(path: str | Path) -> Report:
    """Check the EDS/DCF at ``path`` (ConfigError when canopen cannot read it at all).

    Parameters
    ----------
    path : str or Path
        The EDS or DCF.

    Returns
    -------
    Report
        What was found.

    Raises
    ------
    ConfigError
        No such file, or one canopen cannot read at all.
    """
    path = Path(path)
    report = Report(path)
    raw = path.read_bytes() if path.is_file() else None
    if raw is None:
        raise ConfigError(path, "", "no such EDS/DCF file")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        text = raw.decode("cp1252", errors="replace")
        report.findings.append("not UTF-8 (read as Windows-1252)")
    cfg = _CaseKeeping(strict=False, interpolation=None)
    try:
        cfg.read_string(text, str(path))
    except configparser.Error as exc:
        raise ConfigError(path, "", f"not an INI file as CiA 306 describes: {exc}") from exc
    report.findings += _cia306(cfg)
    report.lely = _lely(path)
    try:
        report.drive = _drive(load_od(path, 1))
    except ConfigError as exc:
        report.findings.append(f"canopen cannot import it ({exc.problem}); drive-bridge cannot use it either")
    return report


def _cia306(cfg: configparser.RawConfigParser) -> list[str]:
    out = []
    sections = {s.upper(): s for s in cfg.sections()}
    types: dict[str, int] = {}
    listed = set()
    for name in LISTS:
        if name in cfg:
            listed |= {
                int(v, 0)
                for k, v in cfg[name].items()
                if k.lower() != "supportedobjects" and _int(v) is not None
            }
    described = set()
    for section in cfg.sections():
        m = OBJECT.match(section)
        if not m:
            continue
        index = int(m.group(1), 16)
        if not m.group(2):
            described.add(index)
        keys = {k.lower(): k for k in cfg[section]}
        extra = sorted(k for lk, k in keys.items() if lk not in OBJECT_KEYS)
        if extra:
            out.append(f"[{section}]: {', '.join(extra)} (no such key in CiA 306)")
        dtype = _int(cfg[section].get("DataType", ""))
        if dtype is not None:
            types[section.upper()] = dtype
        for key in VALUE_KEYS:
            value = cfg[section].get(key)
            if value is None or value.strip() == "" or dtype is None:
                continue
            problem = _value_problem(value.strip(), dtype)
            if problem:
                out.append(f"[{section}] {key}={value.strip()}: {problem}")
    for index in MANDATORY:
        if f"{index:04X}" not in sections:
            out.append(f"mandatory object 0x{index:04X} is not described")
    if listed:
        for index in sorted(listed - described):
            out.append(f"object 0x{index:04X} is listed but has no [{index:04X}] section")
        for index in sorted(described - listed):
            out.append(f"[{index:04X}] is described but not listed in {'/'.join(LISTS)}")
    return out


def _int(text: str) -> int | None:
    try:
        return int(text.strip(), 0)
    except (ValueError, AttributeError):
        return None


def _value_problem(value: str, dtype: int) -> str | None:
    if "$NODEID" in value.upper():
        return None if NODEID.match(value) else "$NODEID in another form than $NODEID+value"
    if dtype in datatypes.FLOAT_TYPES:
        return (
            None
            if _int(value) is not None
            else "a decimal REAL: CiA 306 tools (Lely) read a REAL as its IEEE 754 bit pattern (0x...)"
        )
    if dtype in INTEGER_TYPES and _int(value) is None:
        return "not an integer (decimal, 0x hexadecimal or 0 octal)"
    return None


def _lely(path: Path) -> list[str] | None:
    """Lely's linter (PyPI dcf-tools) on the file; None when it is not installed.  It says what it
    finds as UserWarnings (``warnings.warn`` without a category); a warning of another kind caught
    meanwhile is not about the file -- a ResourceWarning for a file other code left open, which the
    garbage collector happened to free during the lint, once made the project's EDS "not standard"."""
    try:
        from dcf.lint import lint
        from dcf.parse import parse_file
    except ImportError:
        return None
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            lint(parse_file(str(path)))
        except Exception as exc:  # its parser on a file it cannot take: that is the finding
            return [f"dcf-tools could not read it: {exc}"]
    return [str(w.message) for w in caught if issubclass(w.category, UserWarning)]


def _drive(od: canopen.ObjectDictionary) -> list[str]:
    out = []
    if 0x6502 not in od:
        out.append("modes: no 0x6502 (supported drive modes) in the file")
    elif default(od, 0x6502) is None:
        out.append("modes: 0x6502 has no DefaultValue here; bring-up reads it from the drive")
    else:
        out.append(f"modes (0x6502): {describe_modes(default(od, 0x6502))}")
    for role, indices in ROLES.items():
        have = [f"0x{i:04X}" for i in indices if i in od]
        out.append(f"{role}: {', '.join(have) if have else 'none'}")
    rpdo = sum(1 for i in range(0x1400, 0x1600) if i in od)
    tpdo = sum(1 for i in range(0x1800, 0x1A00) if i in od)
    out.append(f"PDOs: {rpdo} receive, {tpdo} transmit")
    return out
