"""Which CAN bus: python-can's conventions, as its own tools follow them.

The interface, channel and bitrate come from the command line (``-i``, ``-c``, ``-b``), else
bus.yml's ``master``, else python-can's configuration (``can.util.load_config``: its
``can.rc``, the environment ``CAN_INTERFACE`` / ``CAN_CHANNEL`` / ``CAN_BITRATE`` /
``CAN_CONFIG``, the files ``/etc/can.conf``, ``~/.can``, ``~/.canrc``).  Every other key of
python-can's configuration and ``master.can_options`` goes to ``can.Bus`` as it is (serial,
app_name, fd, data_bitrate ...), except what would change how the master works:
``receive_own_messages`` would put each SYNC and RPDO on the master's own bus twice, so it is
set False with a note.
"""

from __future__ import annotations

from dataclasses import replace

import can

from .config import BusConfig
from .errors import ConfigError

NEUTRALISED = {
    "receive_own_messages": (
        False,
        "the master would receive its own SYNC and RPDO frames and count them twice",
    )
}
LINK_KEYS = ("interface", "channel", "bitrate")


def python_can_config() -> dict:
    """python-can's own configuration (``can.rc``, environment, files), merged in its order
    without its check of the interface name (there may be none: ``--sim`` needs no bus).

    Returns
    -------
    dict
        The keys it sets (interface, channel, bitrate, the interface's own).
    """
    out: dict = {}
    sources = (lambda: can.rc, can.util.load_environment_config, lambda: can.util.load_file_config(None))
    for source in sources:
        for key, value in dict(source() or {}).items():
            key = "interface" if key == "bustype" else key
            if key not in out:
                out[key] = can.util.cast_from_string(value) if isinstance(value, str) else value
    return out


def resolve(
    config: BusConfig,
    interface: str | None = None,
    channel: str | int | None = None,
    bitrate: int | None = None,
) -> BusConfig:
    """``config`` with its master's interface, channel, bitrate and bus arguments filled in as
    the module docstring says, and notes on where they came from.

    Parameters
    ----------
    config : BusConfig
        The bus configuration.
    interface, channel : str, optional
        As the command line gives them (``-i``, ``-c``).
    bitrate : int, optional
        [bit/s], as the command line gives it.

    Returns
    -------
    BusConfig
        The configuration, its master's bus filled in.

    Raises
    ------
    ConfigError
        An interface python-can refuses (``master.interface``), or a bitrate that is not a
        number (``master.bitrate``).
    """
    m = config.master
    cli = {"interface": interface, "channel": channel, "bitrate": bitrate}
    yml = {"interface": m.interface, "channel": m.channel, "bitrate": m.bitrate}
    given = {k: (cli[k] if cli[k] is not None else yml[k]) for k in LINK_KEYS}
    own = python_can_config()
    merged = {**own, **m.can_options, **{k: v for k, v in given.items() if v is not None}}
    if merged.get("interface") is not None:
        try:
            merged = can.util.load_config(config=merged)  # python-can checks the interface name
        except (can.CanError, ValueError) as exc:
            raise ConfigError(config.path, "master.interface", f"python-can refuses it: {exc}") from exc
    notes = list(m.notes)
    taken = [k for k in LINK_KEYS if given[k] is None and merged.get(k) is not None]
    if taken:
        notes.append(
            f"{', '.join(f'{k} {merged[k]!r}' for k in taken)} from python-can's configuration "
            f"(CAN_INTERFACE / CAN_CHANNEL / CAN_BITRATE, ~/.canrc, /etc/can.conf)"
        )
    from_cli = [k for k in LINK_KEYS if cli[k] is not None]
    if from_cli:
        notes.append(f"{', '.join(f'{k} {cli[k]!r}' for k in from_cli)} from the command line")
    options = {k: v for k, v in merged.items() if k not in LINK_KEYS}
    for key, (value, why) in NEUTRALISED.items():
        if key in options and options[key] != value:
            source = "master.can_options" if key in m.can_options else "python-can's configuration"
            notes.append(f"{key} = {options[key]!r} ({source}) set to {value!r}: {why}")
        options[key] = value
    for key in own:
        if key not in LINK_KEYS and key in options and key not in m.can_options and key not in NEUTRALISED:
            notes.append(f"{key} = {options[key]!r} from python-can's configuration, passed to the bus")
    bit = merged.get("bitrate")
    try:
        bit = None if bit is None else int(bit)
    except (TypeError, ValueError) as exc:
        raise ConfigError(
            config.path, "master.bitrate", f"python-can's configuration gives bitrate {bit!r}, not a number"
        ) from exc
    master = replace(
        m,
        interface=merged.get("interface"),
        channel=merged.get("channel"),
        bitrate=bit,
        can_options=options,
        notes=tuple(notes),
    )
    return replace(config, master=master)
