"""What a simulated drive takes from its drive's description beyond the EDS/DCF.

A simulated drive is built from an EDS/DCF: its object dictionary, the modes its
0x6502 lists, its feedback objects and the identity it names come from the file
itself.  What a file does not say -- the units the drive reports in, an encoder
resolution where there is no 0x608F, the supported modes where 0x6502 has no
default, which drive profile holds its gain objects -- is given here per file.
Values marked as the simulation's choice stand for one plausible drive set-up,
not for a vendor document.
"""

from __future__ import annotations

import configparser
import math
from dataclasses import dataclass
from functools import cache
from pathlib import Path

from ..cia.objects import (
    CURRENT_ACTUAL,
    FOLLOWING_ERROR_TIMEOUT,
    MAX_TORQUE,
    POSITION_ENCODER_RESOLUTION,
    PROFILE_ACCELERATION,
    PROFILE_VELOCITY,
    QUICK_STOP_DECELERATION,
)
from ..cia.od import load_od
from ..resources import PROJECT_EDS, vendor_dir


@dataclass(frozen=True)
class DriveSpec:
    """What a simulated drive of a vendor's EDS/DCF is.

    Parameters
    ----------
    profile : str
        The drive profile whose objects and scales hold the gains (and model).
    factory_in_file : bool
        The file itself holds the factory gains and the motor data (0x2002: the project's drive).
    increments_per_rev : int, optional
        The encoder, where the file has no 0x608F default.
    velocity_unit : {"inc/s", "rpm"}
        Of 0x606C and every velocity/acceleration object (inc/s and inc/s²; rpm and rpm/s).
    current_unit : {"permille", "mA"}
        Of 0x6078 (per mille of the rated current 0x6075, or mA) and of any vendor object in
        ``current_objects``.
    supported_modes : int, optional
        0x6502, where the file has no default.
    current_objects : tuple of int
        The objects reporting the averaged current.
    """

    profile: str
    factory_in_file: bool = False
    increments_per_rev: int | None = None
    velocity_unit: str = "inc/s"
    current_unit: str = "permille"
    supported_modes: int | None = None
    current_objects: tuple[int, ...] = (CURRENT_ACTUAL,)


#: by EDS/DCF file name
SPECS = {
    PROJECT_EDS.name: DriveSpec("drive_bridge_servo", factory_in_file=True),
    # EPOS2: velocities in rpm (0x608C = 0xA4 in its EDS), current actual in mA; 0x6502 is left to
    # the drive: PP, PV, homing, IP and maxon's position/velocity/current modes (bits 16-18).
    # 16384 increments per revolution: a 4096-count encoder, quadrature (the simulation's choice).
    # 0x2027 "Current Actual Value Averaged" reports the same averaged current.
    "maxon_epos2_50-5.eds": DriveSpec(
        "maxon_epos2",
        increments_per_rev=16384,
        velocity_unit="rpm",
        current_unit="mA",
        supported_modes=0x00070065,
        current_objects=(CURRENT_ACTUAL, 0x2027),
    ),
    # C5-E: 0x608F:1 has no default; 65536 increments per revolution (the simulation's choice).
    "nanotec_C5-E-2-09.eds": DriveSpec("nanotec_c5e", increments_per_rev=65536),
    # iPOS: no 0x608F; 16384 increments per revolution (the simulation's choice).
    "technosoft_iPOS.eds": DriveSpec("technosoft_ipos", increments_per_rev=16384),
    # PRBT: no 0x608F; 2^20 increments per revolution (the simulation's choice).
    "pilz_prbt_0_1.dcf": DriveSpec("pilz_prbt", increments_per_rev=2**20),
}


def spec_for(eds_path: str | Path) -> DriveSpec:
    """The description of the drive an EDS/DCF is for: by its file name, else by the vendor and
    product number of its [DeviceInfo] (a DCF exported from one of the files); ValueError naming
    the known files.

    Parameters
    ----------
    eds_path : str or Path
        The EDS/DCF.

    Returns
    -------
    DriveSpec
        The description.

    Raises
    ------
    ValueError
        A file of no known drive, naming the known files.
    """
    name = Path(eds_path).name
    if name in SPECS:
        return SPECS[name]
    ident = _identity(Path(eds_path))
    for known, spec in SPECS.items():
        path = PROJECT_EDS if known == PROJECT_EDS.name else vendor_dir() / known
        if ident is not None and path.is_file() and _identity(path) == ident:
            return spec
    raise ValueError(
        f"the simulator has no drive for {name} (it has: {', '.join(SPECS)}, or a file with one of "
        f"their vendor and product numbers)"
    )


def _identity(path: Path) -> tuple[int, int] | None:
    """(VendorNumber, ProductNumber) of an EDS/DCF's [DeviceInfo]; None when it has none."""
    cfg = configparser.RawConfigParser(strict=False)
    try:
        cfg.read_string(path.read_bytes().decode("utf-8", errors="replace"))
        return int(cfg["DeviceInfo"]["VendorNumber"], 0), int(cfg["DeviceInfo"]["ProductNumber"], 0)
    except (OSError, KeyError, ValueError, configparser.Error):
        return None


@dataclass(frozen=True)
class Factory:
    """The factory set-up every simulated drive starts from, SI: the project drive's EDS
    defaults, so that each vendor drive runs the same loops on the same plant.

    Parameters
    ----------
    gains : dict of str to float
        KpP, FwF, KpS, KiS, KpC, KiC.
    max_torque_permille : int
        0x6072.
    quick_stop_rad_s2 : float
        0x6085 [rad/s²].
    profile_velocity_rad_s : float
        0x6081 [rad/s].
    profile_acceleration_rad_s2 : float
        0x6083, 0x6084 [rad/s²].
    fe_timeout_ms : int
        0x6066 [ms].
    """

    gains: dict[str, float]
    max_torque_permille: int
    quick_stop_rad_s2: float
    profile_velocity_rad_s: float
    profile_acceleration_rad_s2: float
    fe_timeout_ms: int


@cache
def factory() -> Factory:
    od = load_od(PROJECT_EDS, 1)

    def default(index: int, sub: int = 0) -> int | float:
        var = od.get_variable(index, sub)
        if var is None or var.default is None:
            raise ValueError(f"{PROJECT_EDS.name} has no default for 0x{index:04X}:{sub}")
        return var.default

    inc_per_rad = (
        default(POSITION_ENCODER_RESOLUTION, 1) / default(POSITION_ENCODER_RESOLUTION, 2) / (2 * math.pi)
    )
    names = ("KpP", "FwF", "KpS", "KiS", "KpC", "KiC")
    return Factory(
        {n: float(default(0x2000, i + 1)) for i, n in enumerate(names)},
        int(default(MAX_TORQUE)),
        default(QUICK_STOP_DECELERATION) / inc_per_rad,
        default(PROFILE_VELOCITY) / inc_per_rad,
        default(PROFILE_ACCELERATION) / inc_per_rad,
        int(default(FOLLOWING_ERROR_TIMEOUT)),
    )
