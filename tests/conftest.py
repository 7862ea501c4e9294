"""Shared fixtures: simulated robots on private virtual-bus channels, in lockstep."""
from __future__ import annotations

import itertools
from pathlib import Path

import canopen
import pytest

from drive_bridge.paper import TABLE_II
from drive_bridge.sim.config import DEFAULT_CONFIG, Motor, SimAxis, SimConfig, load_sim_config
from drive_bridge.sim.lockstep import LockstepLink
from drive_bridge.sim.robot import SimRobot

ROOT = Path(__file__).resolve().parents[1]
EDS = ROOT / "eds" / "drive_bridge_servo.eds"
BUS_CONFIG = ROOT / "config" / "bus.yml"
_channels = itertools.count(1)

PAPER = TABLE_II


def clean_config(noise: float = 0.0, seed: int = 0, effects: dict | None = None) -> SimConfig:
    """The robot without hidden effects; ``effects`` = {axis: {name: {kernel param: value}}}."""
    axes = {}
    for i, (name, p) in enumerate(PAPER.items()):
        axes[name] = SimAxis(name=name, node_id=i + 1, serial=100 + i, torque_noise_Nm=noise,
                             motor=Motor(), effects=(effects or {}).get(name, {}), **p)
    return SimConfig(axes=axes, seed=seed)


class Bench:
    """A simulated robot with a lockstep master link and canopen RemoteNodes for its drives."""

    open: list["Bench"] = []

    def __init__(self, config: SimConfig):
        Bench.open.append(self)
        channel = f"test-{next(_channels)}"
        self.robot = SimRobot(config, channel)
        self.link = LockstepLink(self.robot, channel)
        self.net = self.link.network
        self.nodes = {}
        for name, axis in config.axes.items():
            node = canopen.RemoteNode(axis.node_id, canopen.import_od(str(EDS), axis.node_id))
            self.net.add_node(node)
            self.nodes[name] = node

    def close(self):
        if self in Bench.open:
            Bench.open.remove(self)
            self.link.close()


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


@pytest.fixture
def shipped_sim_config():
    return load_sim_config(DEFAULT_CONFIG)
