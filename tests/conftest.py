"""Fixtures: simulated robots on private virtual-bus channels, in lockstep (helpers in support.py)."""
from __future__ import annotations

import os

import pytest

from drive_bridge.sim.config import DEFAULT_CONFIG, SimConfig, load_sim_config

from .support import VENDOR_EDS, Bench, clean_config

os.environ.setdefault("DRIVE_BRIDGE_VENDOR_EDS", str(VENDOR_EDS))     # vendor files, read in place


@pytest.fixture
def bench():
    benches = []

    def make(config: SimConfig | None = None) -> Bench:
        b = Bench(config or clean_config())
        benches.append(b)
        return b
    yield make
    for b in benches:
        b.close()


@pytest.fixture(autouse=True)
def _close_benches():
    """Benches a test opened without the fixture are closed after it."""
    yield
    for b in list(Bench.open):
        b.close()


@pytest.fixture
def shipped_sim_config():
    return load_sim_config(DEFAULT_CONFIG)
