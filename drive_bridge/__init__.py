"""drive-bridge: commission the servo axes of a Cartesian robot over CANopen.

The public API, each name imported on first use (``import drive_bridge`` stays light for the
command line):

=====================  ==================================================================
:class:`Session`       the drives of a bus configuration, reached over a link: scan,
                       bring-up, identities, how each axis is held (canopen's ``Network``)
:class:`Options`       how a session or a commissioning reaches the drives and runs
:func:`open_link`      the link the master talks through: the configured bus or the
                       simulated robot
:func:`load_bus_config`  bus.yml, checked: one clear error naming file and key
:func:`identify`       J, c0, c1 and the effects the residual shows, per axis of a log
:func:`tune`           the cascade gains of every axis from its identified model
:func:`write_drives`   the write step: every value checked, one transaction over every drive
:func:`commission`     scan → bring-up → campaign → identify → tune → write → validate
=====================  ==================================================================
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from .version import __version__

#: name -> the module that holds it
_PUBLIC = {
    "Session": "drive_bridge.session",
    "Options": "drive_bridge.session",
    "open_link": "drive_bridge.connect",
    "load_bus_config": "drive_bridge.config",
    "identify": "drive_bridge.ident.identify",
    "tune": "drive_bridge.tuning.tune",
    "write_drives": "drive_bridge.params.write",
    "commission": "drive_bridge.commissioning.run",
}

__all__ = [
    "Options",
    "Session",
    "__version__",
    "commission",
    "identify",
    "load_bus_config",
    "open_link",
    "tune",
    "write_drives",
]

if TYPE_CHECKING:
    from .commissioning.run import commission
    from .config import load_bus_config
    from .connect import open_link
    from .ident.identify import identify
    from .params.write import write_drives
    from .session import Options, Session
    from .tuning.tune import tune


def __getattr__(name: str) -> Any:
    if name in _PUBLIC:
        value = getattr(importlib.import_module(_PUBLIC[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'drive_bridge' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_PUBLIC))
