"""Files that ship inside the package, found with :mod:`importlib.resources`.

``drive_bridge/data`` holds the project's EDS (``eds/``) and bus configurations
(``config/``); drive profiles live beside their reader (``params/profiles``) and
the simulated robot beside the simulator (``sim/robot.yaml``).  The package is
installed as files (wheel or source tree), so each resource has a path on disk:
canopen and the YAML readers take paths, and a bus.yml names its EDS by a path
relative to itself.
"""

from __future__ import annotations

import os
from importlib import resources
from pathlib import Path


def shipped(*parts: str) -> Path:
    """A file of the installed package.

    Parameters
    ----------
    *parts : str
        Its path under ``drive_bridge/`` (``"profiles", "maxon_epos2.yaml"``).

    Returns
    -------
    Path
        ``drive_bridge/<parts...>``.
    """
    return Path(str(resources.files("drive_bridge").joinpath(*parts)))


def data(*parts: str) -> Path:
    """A file shipped with the package: the project's EDS and bus configurations.

    Parameters
    ----------
    *parts : str
        Its path under ``drive_bridge/data`` (``"config", "bus.yml"``).

    Returns
    -------
    Path
        ``drive_bridge/data/<parts...>``.
    """
    return shipped("data", *parts)


#: the project's drive (the simulated one): its EDS
PROJECT_EDS = data("eds", "drive_bridge_servo.eds")
#: the bus configuration of the simulated robot, the default of every command
DEFAULT_BUS_CONFIG = data("config", "bus.yml")


def vendor_dir() -> Path:
    """Where vendor EDS/DCF files are read in place (they never ship with drive-bridge).

    A bus.yml ``dcf`` and a profile ``eds`` starting with ``vendor/`` name a file there.

    Returns
    -------
    Path
        ``$DRIVE_BRIDGE_VENDOR_EDS``, else ``../shared/eds-vendor`` or ``shared/eds-vendor`` from
        the working directory (the first, where neither exists).
    """
    if "DRIVE_BRIDGE_VENDOR_EDS" in os.environ:
        return Path(os.environ["DRIVE_BRIDGE_VENDOR_EDS"])
    here = Path.cwd()
    found = [d for d in (here.parent / "shared" / "eds-vendor", here / "shared" / "eds-vendor") if d.is_dir()]
    return found[0] if found else here.parent / "shared" / "eds-vendor"
