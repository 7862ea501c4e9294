"""Helpers the tests share: paths, the paper's plant, simulated robots on private virtual-bus
channels in lockstep, and small readers.  Fixtures built on them are in conftest.py."""

from __future__ import annotations

import itertools
import os
import select
import shutil
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import canopen
import numpy as np
import yaml

from drive_bridge.cia.multicast import UDP_GROUP
from drive_bridge.cia.od import load_od
from drive_bridge.config import load_bus_config
from drive_bridge.paper import TABLE_II
from drive_bridge.resources import DEFAULT_BUS_CONFIG, PROJECT_EDS
from drive_bridge.sim.lockstep import LockstepLink
from drive_bridge.sim.process import free_port
from drive_bridge.sim.robot import SimRobot
from drive_bridge.sim.robot_config import Motor, SimAxis, SimConfig

EDS = PROJECT_EDS
BUS_CONFIG = DEFAULT_BUS_CONFIG
PAPER = TABLE_II
_channels = itertools.count(1)


def clean_config(noise: float = 0.0, seed: int = 0, effects: dict | None = None) -> SimConfig:
    """The robot without hidden effects; ``effects`` = {axis: {name: {kernel param: value}}}."""
    axes = {}
    for i, (name, p) in enumerate(PAPER.items()):
        axes[name] = SimAxis(
            name=name,
            node_id=i + 1,
            serial=100 + i,
            torque_noise_Nm=noise,
            motor=Motor(),
            effects=(effects or {}).get(name, {}),
            **p,
        )
    return SimConfig(axes=axes, seed=seed)


class Bench:
    """A simulated robot with a lockstep master link and canopen RemoteNodes for its drives."""

    open: list[Bench] = []

    def __init__(self, config: SimConfig, eds: Path = EDS):
        """Every drive built from ``eds`` (the project's drive by default, or a vendor file)."""
        Bench.open.append(self)
        channel = f"test-{next(_channels)}"
        self.robot = SimRobot(config, channel, eds=eds)
        self.link = LockstepLink(self.robot, channel)
        self.net = self.link.network
        self.nodes = {}
        for name, axis in config.axes.items():
            node = canopen.RemoteNode(axis.node_id, load_od(eds, axis.node_id))
            self.net.add_node(node)
            self.nodes[name] = node

    def close(self):
        if self in Bench.open:
            Bench.open.remove(self)
            self.link.close()


def quick_config(path: Path = BUS_CONFIG, **campaign):
    """A bus configuration (default the shipped one) with a campaign of a few seconds per axis."""
    cfg = load_bus_config(path)
    return replace(cfg, campaign=replace(cfg.campaign.quick(), **campaign))


def read_csv(path):
    """Column names and values of a log CSV."""
    with open(path) as f:
        names = f.readline().strip().split(",")
    return names, np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)


def bus_yml_beside(tmp_path: Path, old: str = "", new: str = "") -> Path:
    """The shipped bus.yml copied to ``tmp_path`` (one text replaced), its EDS path made absolute."""
    text = BUS_CONFIG.read_text().replace(old, new, 1) if old else BUS_CONFIG.read_text()
    cfg = tmp_path / "bus.yml"
    cfg.write_text(text.replace("../eds/", str(EDS.parent) + "/"))
    return cfg


def wait_for(stream, text: str, timeout: float) -> str:
    """Lines of ``stream`` up to the first that holds ``text``."""
    seen, deadline = [], time.time() + timeout
    while time.time() < deadline:
        if select.select([stream], [], [], 0.5)[0]:
            line = stream.readline()
            seen.append(line)
            if text in line:
                return "".join(seen)
    raise AssertionError(f"{text!r} did not come within {timeout} s; got {''.join(seen)!r}")


def start_sim(tmp_path: Path) -> tuple[subprocess.Popen, Path, int]:
    """``drive-bridge sim`` started as the docs say, on udp_multicast (python-can's IPv4 group, a
    free port), its bus.yml in ``tmp_path``, once it says ready: (the process, the bus.yml, the port)."""
    port = free_port()
    cfg = bus_yml_beside(tmp_path)
    doc = yaml.safe_load(cfg.read_text())
    doc["master"].update(interface="udp_multicast", channel=UDP_GROUP, can_options={"port": port})
    cfg.write_text(yaml.safe_dump(doc))
    drives = subprocess.Popen(
        [sys.executable, "-m", "drive_bridge", "sim", "--config", str(cfg), "--port", str(port)],
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )
    try:
        wait_for(drives.stdout, "ready", 120)
    except BaseException:
        drives.terminate()
        raise
    return drives, cfg, port


def tool(name: str) -> str | None:
    """A third-party command (dcfchk, dcfgen, tshark) from the test environment or PATH; None when absent."""
    return shutil.which(
        name, path=os.pathsep.join([os.path.dirname(sys.executable), os.environ.get("PATH", "")])
    )


def follows_schema(doc: dict, name: str) -> dict:
    """``doc`` names schema ``drive-bridge/<name>`` at the current version and the JSON Schema the
    package ships for it accepts it (jsonschema, in the test extra); every float in it carries at
    most the digits a result means (drive_bridge.outputs.SIGNIFICANT)."""
    import json

    import jsonschema

    from drive_bridge.outputs import SCHEMA_VERSION, SIGNIFICANT
    from drive_bridge.resources import data

    assert doc["schema"] == f"drive-bridge/{name}" and doc["schema_version"] == SCHEMA_VERSION
    jsonschema.validate(doc, json.loads(data("schemas", f"{name}.schema.json").read_text()))

    def floats(x):
        if isinstance(x, dict):
            for v in x.values():
                yield from floats(v)
        elif isinstance(x, list):
            for v in x:
                yield from floats(v)
        elif isinstance(x, float):
            yield x

    for f in floats(doc):
        assert f.is_integer() or float(f"{f:.{SIGNIFICANT}g}") == f, f"{f!r}: more digits than it means"
    return doc


def decodes_to_the_log(out: Path) -> None:
    """``decoded.csv`` (``decode`` of the run's trace) is the live ``log.csv``, except rows the live
    log marked missing (a reply that reached the master after its row was written, on the wall
    clock of an overloaded machine), which the trace recovers; meta.yaml counts them."""
    import yaml

    live, decoded = (out / "log.csv").read_text().splitlines(), (out / "decoded.csv").read_text().splitlines()
    assert len(live) == len(decoded)
    differ = [i for i, (a, b) in enumerate(zip(live, decoded)) if a != b]
    assert all(live[i].endswith(",0") for i in differ), [live[i] for i in differ[:3]]
    missing = yaml.safe_load((out / "meta.yaml").read_text())["counts"]["samples_missing"]
    assert len(differ) <= sum(missing.values())
