"""A simulated drive's object storage: the values its SDO server holds (canopen's ``LocalNode``
data store, as raw bytes), decoded once and kept (a drive reads its objects every loop period),
the objects it measures or computes instead of storing (read live, never kept), and the
parameter set saved by 0x1010 that a reset restores."""

from __future__ import annotations

import copy
from collections.abc import Callable
from typing import Any

from canopen import LocalNode

from ..cia.od import variable


class ObjectStorage:
    """The objects of ``node`` (a canopen ``LocalNode``); ``live`` maps the index of each object
    the drive measures or computes to the callable that reads it now.

    Parameters
    ----------
    node : LocalNode
        canopen's local node (its data store is the SDO server's).
    live : dict of int to callable
        Index -> the callable that reads a measured or computed object now.
    """

    def __init__(self, node: LocalNode, live: dict[int, Callable[[], int]]):
        self.node = node
        self.od = node.object_dictionary
        self.live = live
        #: the parameter set 0x1010 saved: what a reset restores (empty after 0x1011: the defaults)
        self.saved: dict[int, dict[int, bytes]] = {}
        self._values: dict[tuple[int, int], Any] = {}  # decoded values of the stored objects
        self._absent: set[tuple[int, int]] = set()  # objects the drive's EDS/DCF does not have

    def get(self, index: int, sub: int = 0) -> Any:
        """An object's current value, as the SDO server would return it.

        Parameters
        ----------
        index : int
            The index.
        sub : int
            The subindex.

        Returns
        -------
        object
            The value.

        Raises
        ------
        KeyError
            The drive has no such object.
        """
        try:
            return self._values[(index, sub)]
        except KeyError:
            value = variable(self.od, index, sub).decode_raw(self.node.get_data(index, sub))
            if index not in self.live:
                self._values[(index, sub)] = value
            return value

    def get_or(self, index: int, sub: int, fallback: Any) -> Any:
        """An object's value, or ``fallback`` where the drive has no such object.

        Parameters
        ----------
        index, sub : int
            The object.
        fallback : object
            The value where there is none.

        Returns
        -------
        object
            The value.
        """
        value = self._values.get((index, sub))  # (held: the object exists)
        if value is not None:
            return value
        if (index, sub) in self._absent:
            return fallback
        if self.od.get_variable(index, sub) is None:
            self._absent.add((index, sub))  # (its object dictionary does not change)
            return fallback
        return self.get(index, sub)

    def getter(self, index: int, sub: int) -> Callable[[], Any]:
        """The callable that reads an object now (a TPDO samples it so).

        Parameters
        ----------
        index, sub : int
            The object.

        Returns
        -------
        callable
            The reader.
        """
        return self.live.get(index) or (lambda: self.get(index, sub))

    def set(self, index: int, sub: int, value: Any) -> None:
        """Hold ``value`` as the object's (the drive's own doing: factory state, measured status).

        Parameters
        ----------
        index, sub : int
            The object.
        value : object
            The value.
        """
        self.node.data_store.setdefault(index, {})[sub] = variable(self.od, index, sub).encode_raw(value)
        self._values[(index, sub)] = value

    def written(self, index: int, sub: int, value: Any) -> None:
        """``value`` written to the object by SDO: the drive reads it from now on (the SDO server
        stores its bytes after the drive took it).

        Parameters
        ----------
        index, sub : int
            The object.
        value : object
            The value written.
        """
        if index not in self.live:
            self._values[(index, sub)] = value

    def keep(self, index: int, sub: int, raw: bytes, value: Any) -> None:
        """Hold a value a PDO wrote as the object's (SDO reads it so); a measured object keeps its own.

        Parameters
        ----------
        index, sub : int
            The object.
        raw : bytes
            Its bytes.
        value : object
            The value.
        """
        if index not in self.live and self._values.get((index, sub)) != value:
            self.node.data_store.setdefault(index, {})[sub] = raw
            self._values[(index, sub)] = value

    def clear(self) -> None:
        """Nothing stored (the factory state is then written anew)."""
        self.node.data_store.clear()
        self._values.clear()

    def save(self) -> None:
        """0x1010: the current values are the set a reset restores."""
        self.saved = copy.deepcopy(self.node.data_store)

    def restore(self, communication_only: bool = False) -> None:
        """A reset: the saved set back (``communication_only``: only the communication area
        0x1000-0x1FFF; the rest as it is).

        Parameters
        ----------
        communication_only : bool
            Only the communication area.
        """
        restored = copy.deepcopy(self.saved)
        if communication_only:
            restored.update({i: v for i, v in self.node.data_store.items() if i >= 0x2000})
        self.node.data_store = restored
        self._values.clear()
