"""The consistency check of identification measured over noise seeds of the independent plants
(:mod:`harness.plants`, none of ``drive_bridge.sim``): how often it flags an axis whose J, c0 and
c1 hold, and an axis whose inertia steps halfway through the log (a payload added)."""

from __future__ import annotations

import tempfile
from collections.abc import Callable
from pathlib import Path

import numpy as np

from drive_bridge.ident.identify import identify
from drive_bridge.sim.plantlog import write_log
from harness.plants import campaign_log, closed_loop_log

#: family -> (log of a noise seed whose inertia is (1 + step) times the plant's after halfway,
#: the family in words)
FAMILIES: dict[str, tuple[Callable[[int, float], dict[str, np.ndarray]], str]] = {
    "sines": (
        lambda seed, step: closed_loop_log(
            np.arange(40000) / 1000, seed=seed, payload=(20.0, 1e-4 * (1 + step)) if step else None
        ),
        "two sines and friction under a cascade, 40 s at 1 kHz",
    ),
    "campaign": (
        lambda seed, step: campaign_log(seed=seed, payload=(49.5, 8.9e-5 * (1 + step)) if step else None),
        "the paper's nine levels of trapezoids on a belt axis like X, 99 s at 500 Hz",
    ),
}


def checked(family: str, seeds: range, step: float = 0.0) -> list[dict]:
    """The consistency answer of each seed's log of ``family`` identified as a user would."""
    make = FAMILIES[family][0]
    with tempfile.TemporaryDirectory() as tmp:
        return [
            identify(write_log(Path(tmp) / "log.csv", make(seed, step)))["y"].diagnostics.consistency
            for seed in seeds
        ]
