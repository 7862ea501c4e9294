"""Strict reading of YAML configuration: every error names the file and the key."""

from __future__ import annotations

import copy
import functools
import math
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any, TypeGuard

import yaml

from .errors import ConfigError


def load_yaml(path: str | Path) -> dict:
    """Read a YAML mapping with ``yaml.safe_load`` (a text read before: parsed once); errors name the file.

    Parameters
    ----------
    path : str or Path
        The file.

    Returns
    -------
    dict
        The mapping (a copy of its own).

    Raises
    ------
    ConfigError
        A file that cannot be read, or is not a YAML mapping.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError as exc:
        raise ConfigError(path, "", "file not found") from exc
    except IsADirectoryError as exc:
        raise ConfigError(path, "", "is a directory, not a YAML file") from exc
    except OSError as exc:
        raise ConfigError(path, "", f"cannot read: {exc.strerror}") from exc
    except UnicodeDecodeError as exc:
        raise ConfigError(path, "", f"not UTF-8 text (byte {exc.start}): save it as UTF-8") from exc
    try:
        data = copy.deepcopy(_parsed(text))  # the caller's own objects, as a fresh parse gives
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" at line {mark.line + 1}" if mark else ""
        raise ConfigError(path, "", f"not valid YAML{where}: {getattr(exc, 'problem', exc)}") from exc
    except RecursionError as exc:
        raise ConfigError(path, "", "nested too deeply to be a configuration") from exc
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise ConfigError(path, "", "the top level must be a mapping of keys")
    return data


@functools.lru_cache(maxsize=64)
def _parsed(text: str) -> Any:
    """``yaml.safe_load(text)``, kept for the next read of the same text: a command reads the
    profile and the bus configuration from several places, and PyYAML's pure-Python parser took
    more of the test suite's time than any computation in it (a copy of the parsed data costs a
    sixtieth of a parse: 0.08 ms against 5 ms for bus.yml).  A parse that fails is not kept: it fails again, with its message."""
    return yaml.safe_load(text)


def too_large(value: int) -> str:
    """Why an integer no float can hold is refused (it is not printed: it may have thousands of digits).

    Parameters
    ----------
    value : int
        The integer.

    Returns
    -------
    str
        The words.
    """
    return f"an integer of about 10^{int(value.bit_length() * math.log10(2))} is too large a number"


def _short(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def finite_number(value: Any) -> TypeGuard[float]:
    """A real, finite number (bool is not a number here).

    Parameters
    ----------
    value : object
        The value.

    Returns
    -------
    bool
        Whether it is one.
    """
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return False
    try:
        return math.isfinite(value)
    except OverflowError:  # an integer too large for a float: no number drive-bridge can use
        return False


class Section:
    """A mapping read from a YAML file that knows its path for error messages.

    ``get`` checks types and ranges (a float must be finite); ``done`` refuses keys
    nobody asked for, so a typo is an error instead of a silently ignored setting.

    Parameters
    ----------
    path : Path
        The file it was read from.
    key : str
        Its key in the file (dotted), "" at the top.
    data : object
        Its content (a mapping).

    Raises
    ------
    ConfigError
        ``data`` is not a mapping.
    """

    def __init__(self, path: Path, key: str, data: Any):
        if not isinstance(data, Mapping):
            raise ConfigError(path, key, f"must be a mapping, got {type(data).__name__}")
        self.path = Path(path)
        self.key = key
        self.data = data
        self._used: set[str | int] = set()

    def _name(self, key: str | int) -> str:
        if not key:
            return self.key
        return f"{self.key}.{key}" if self.key else str(key)

    def error(self, key: str | int, problem: str) -> ConfigError:
        """The error naming a key of this section.

        Parameters
        ----------
        key : str or int
            The key.
        problem : str
            What is wrong, and what to do.

        Returns
        -------
        ConfigError
            The error (to raise).
        """
        return ConfigError(self.path, self._name(key), problem)

    def get(
        self,
        key: str | int,
        kind: type | tuple[type, ...],
        default: Any = ...,
        *,
        low: float | None = None,
        high: float | None = None,
        choices: Iterable[Any] | None = None,
    ) -> Any:
        """``key``'s value, checked to be of ``kind`` (a float may be written as an int), finite, within
        [``low``, ``high``] and one of ``choices``; ``default`` where it is absent (``...``: required).

        Parameters
        ----------
        key : str or int
            The key.
        kind : type or tuple of type
            What it must be.
        default : object
            Its value where it is absent; ``...``: required.
        low, high : float, optional
            Its range.
        choices : iterable, optional
            The values it may take.

        Returns
        -------
        object
            The value.

        Raises
        ------
        ConfigError
            Absent where required, of another kind, out of range, not a choice: naming file and key.
        """
        self._used.add(key)
        if key not in self.data:
            if default is ...:
                raise self.error(key, "missing (required)")
            return default
        value: Any = self.data[key]
        kinds = kind if isinstance(kind, tuple) else (kind,)
        if float in kinds and isinstance(value, int) and not isinstance(value, bool):
            try:
                value = float(value)
            except OverflowError as exc:
                raise self.error(key, too_large(value)) from exc
        if isinstance(value, bool) and bool not in kinds or not isinstance(value, kinds):
            names = " or ".join(k.__name__ for k in kinds)
            raise self.error(key, f"must be {names}, got {_short(value)}")
        if isinstance(value, float) and not math.isfinite(value):
            raise self.error(key, f"must be a finite number, got {value!r}")
        if choices is not None and value not in choices:
            raise self.error(key, f"must be one of {', '.join(map(str, choices))}, got {value!r}")
        number: Any = value  # of the kinds asked for: a number where a range is given
        if low is not None and number < low:
            raise self.error(key, f"must be >= {low}, got {value!r}")
        if high is not None and number > high:
            raise self.error(key, f"must be <= {high}, got {value!r}")
        return value

    def accept(self, keys: Iterable[str]) -> set[str]:
        """Mark ``keys`` as known without reading them (keys another tool reads); the ones present.

        Parameters
        ----------
        keys : iterable of str
            The keys.

        Returns
        -------
        set of str
            Those present.
        """
        found = {k for k in keys if k in self.data}
        self._used.update(found)
        return found

    def section(self, key: str | int, required: bool = True) -> Section:
        """A sub-section.

        Parameters
        ----------
        key : str or int
            Its key.
        required : bool
            It must be there (else an empty one where it is absent).

        Returns
        -------
        Section
            The sub-section.

        Raises
        ------
        ConfigError
            Absent where required, or not a mapping.
        """
        value = self.get(key, dict, ... if required else {})
        return Section(self.path, self._name(key), value)

    def keys(self) -> list[Any]:
        """The section's keys, in the file's order.

        Returns
        -------
        list
            The keys.
        """
        return list(self.data.keys())

    def done(self) -> None:
        """Refuse the keys nobody asked for (a typo is an error, not a silently ignored setting).

        Raises
        ------
        ConfigError
            The first unknown key, with the known ones.
        """
        unknown = [k for k in self.data if k not in self._used]
        if unknown:
            known = ", ".join(sorted(map(str, self._used))) or "none"
            raise self.error(str(unknown[0]), f"unknown key (known keys here: {known})")
