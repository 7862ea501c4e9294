"""The rolling log on disk: per axis, the stretches of samples in which it moved, kept until
the window they belong to is identified, then dropped.

Only rows within :data:`MARGIN_S` of motion are kept (a machine that stands still most of the day
fills nothing), each chunk a CSV file whose name holds its first and last time stamp and its
moving time, so that a monitor restarted on the same directory resumes its windows where it
stopped.  A window holds at most :data:`MAX_CHUNKS` files (about 0.7 MB each at 1 kHz): the oldest go first.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..outputs import write_table
from .listen import Chunk

MARGIN_S = 0.5  # the rows this close to motion are kept with it (the filters' run-in)
MAX_CHUNKS = 720  # at most this many chunk files per axis, two hours of samples (the oldest dropped first)
_NAME = re.compile(r"(\d+)_(\d+)_(\d+)\.csv")  # first and last stamp [µs], moving time [ms]


@dataclass(frozen=True)
class Stored:
    """A chunk file: where, its first and last time stamp [s] and its moving time [s].

    Parameters
    ----------
    path : Path
        The file.
    first, last : float
        Its first and last time stamp [s since the epoch].
    moving_s : float
        Its moving time [s].
    """

    path: Path
    first: float
    last: float
    moving_s: float


class RollingLog:
    """The chunks of one axis not yet identified, in ``directory``.

    Parameters
    ----------
    directory : Path
        Where they are kept.
    axis : str
        The axis.
    """

    def __init__(self, directory: Path, axis: str):
        self.axis = axis
        self.directory = directory
        directory.mkdir(parents=True, exist_ok=True)
        self.chunks: list[Stored] = []
        for path in sorted(directory.glob("*.csv")):
            m = _NAME.fullmatch(path.name)
            if m:
                first, last, moving = (int(g) for g in m.groups())
                self.chunks.append(Stored(path, first / 1e6, last / 1e6, moving / 1e3))
            else:  # a file cut short by a crash while written (written whole or not at all)
                path.unlink()
        self.chunks.sort(key=lambda c: c.first)

    @property
    def moving_s(self) -> float:
        """The chunks' moving time [s]."""
        return sum(c.moving_s for c in self.chunks)

    @property
    def first(self) -> float | None:
        """The first chunk's first time stamp [s] (None: no chunk)."""
        return self.chunks[0].first if self.chunks else None

    @property
    def last(self) -> float | None:
        """The last chunk's last time stamp [s] (None: no chunk)."""
        return self.chunks[-1].last if self.chunks else None

    def add(self, chunk: Chunk) -> Stored | None:
        """Keep the rows of ``chunk`` near motion; None where it did not move.

        Parameters
        ----------
        chunk : Chunk
            The samples.

        Returns
        -------
        Stored or None
            The chunk file.
        """
        if not chunk.moving.any() or len(chunk.time) < 2:
            return None
        dt = float(np.median(np.diff(chunk.time)))
        reach = max(1, round(MARGIN_S / dt))
        near = _near(chunk.moving, reach)
        time, values = chunk.time[near], chunk.values[near]
        first, last, moving = round(time[0] * 1e6), round(time[-1] * 1e6), round(chunk.moving_s * 1e3)
        path = self.directory / f"{first}_{last}_{moving}.csv"
        write_table(
            path,
            ["time_s", *chunk.columns],
            np.column_stack([time, values]),
            ["%.6f"] + ["%.9g"] * len(chunk.columns),
        )
        stored = Stored(path, first / 1e6, last / 1e6, moving / 1e3)  # as a restart reads them
        self.chunks.append(stored)
        while len(self.chunks) > MAX_CHUNKS:
            self.chunks.pop(0).path.unlink(missing_ok=True)
        return stored

    def window(self, path: Path) -> tuple[float, float]:
        """Write the chunks as one log at ``path`` (time from the first stamp; the stretches
        between chunks are time gaps the identification does not bridge); their first and
        last time stamp [s].

        Parameters
        ----------
        path : Path
            The log to write.

        Returns
        -------
        first, last : float
            [s since the epoch].
        """
        tables = [np.loadtxt(c.path, delimiter=",", skiprows=1, ndmin=2) for c in self.chunks]
        with open(self.chunks[0].path, encoding="utf-8") as f:
            names = f.readline().strip().split(",")
        table = np.concatenate(tables)
        first = float(table[0, 0])
        table[:, 0] -= first
        write_table(path, names, table, ["%.6f"] + ["%.9g"] * (len(names) - 1))
        return first, float(table[-1, 0]) + first

    def drop(self) -> None:
        """Forget the chunks (their window was identified)."""
        for c in self.chunks:
            c.path.unlink(missing_ok=True)
        self.chunks = []


def _near(moving: np.ndarray, reach: int) -> np.ndarray:
    """Per row: a moving row lies within ``reach`` rows of it."""
    count = np.concatenate([[0], np.cumsum(moving)])
    rows = np.arange(len(moving))
    return count[np.minimum(rows + reach + 1, len(moving))] - count[np.maximum(rows - reach, 0)] > 0
