"""Hostile inputs for every file and value drive-bridge reads, as hypothesis strategies, and the
reader each goes through.  A reader may accept an input or refuse it with a DriveBridgeError (one
clear line, exit 2 or 3); anything else is a traceback, a defect.

Used by tests/test_fuzz.py (bounded, seconds) and tools/fuzz_inputs.py (long, seeded, counted).
"""

from __future__ import annotations

import copy
import json
import math
import shutil
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import yaml
from hypothesis import strategies as st

from drive_bridge.cia.od import load_od
from drive_bridge.cli import main
from drive_bridge.config import load_bus_config
from drive_bridge.ident.logdata import read_log
from drive_bridge.logs import decode_trace
from drive_bridge.params.check import check_set
from drive_bridge.params.profile import PROFILE_DIR, load_profile
from drive_bridge.resources import DEFAULT_BUS_CONFIG, PROJECT_EDS
from drive_bridge.sim.robot_config import DEFAULT_CONFIG as SIM_CONFIG
from drive_bridge.sim.robot_config import load_sim_config
from drive_bridge.tuning.tune import read_identify_json, read_tune_json, tune

#: values nobody should write in a configuration, and some that look almost right
HOSTILE = st.one_of(
    st.integers(min_value=-(2**70), max_value=2**70),
    st.sampled_from([0, -1, 1, 2**31, 2**64, 10**400 // 10**300]),
    st.sampled_from([10**400, -(10**400), 10**309]),  # integers no float can hold
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([float("nan"), float("inf"), -0.0, 1e308]),
    st.text(max_size=12),
    st.booleans(),
    st.none(),
    st.lists(st.integers(-5, 5), max_size=4),
    st.dictionaries(st.text(max_size=4), st.integers(), max_size=3),
)


def _paths(doc, prefix=()):
    """Every key path of a nested mapping/list."""
    if isinstance(doc, dict):
        for k, v in doc.items():
            yield prefix + (k,)
            yield from _paths(v, prefix + (k,))
    elif isinstance(doc, list):
        for i, v in enumerate(doc):
            yield prefix + (i,)
            yield from _paths(v, prefix + (i,))


def _set(doc, path, value):
    for k in path[:-1]:
        doc = doc[k]
    doc[path[-1]] = value


@st.composite
def mutated_yaml(draw, base: dict) -> str:
    """``base`` with one to three values replaced by hostile ones, keys dropped or added, or the
    text itself damaged (bytes that are not UTF-8, deep nesting, truncation)."""
    doc = copy.deepcopy(base)
    paths = list(_paths(doc))
    for _ in range(draw(st.integers(1, 3))):
        path = draw(st.sampled_from(paths))
        action = draw(st.sampled_from(["replace", "replace", "drop", "add"]))
        try:
            if action == "replace":
                _set(doc, path, draw(HOSTILE))
            elif action == "drop":
                parent = doc
                for k in path[:-1]:
                    parent = parent[k]
                del parent[path[-1]]
            else:
                _set(doc, path[:-1] + (draw(st.text(min_size=1, max_size=6)),), draw(HOSTILE)) if len(
                    path
                ) > 1 and isinstance(_get(doc, path[:-1]), dict) else None
        except (KeyError, IndexError, TypeError):
            pass
    text = yaml.safe_dump(doc, allow_unicode=True)
    damage = draw(st.sampled_from(["none", "none", "none", "bytes", "deep", "truncate"]))
    if damage == "deep":
        depth = draw(st.integers(50, 1500))
        text += "\nextra: " + "[" * depth + "0" + "]" * depth
    elif damage == "truncate":
        text = text[: draw(st.integers(0, len(text)))]
    elif damage == "bytes":
        return text.encode() + draw(st.binary(min_size=1, max_size=8)) + b"\xff\xfe"
    return text


def _get(doc, path):
    for k in path:
        doc = doc[k]
    return doc


@st.composite
def mutated_eds(draw) -> bytes:
    """The project's EDS with values, lines or bytes damaged."""
    lines = PROJECT_EDS.read_text().splitlines()
    for _ in range(draw(st.integers(1, 4))):
        i = draw(st.integers(0, len(lines) - 1))
        action = draw(st.sampled_from(["value", "drop", "garbage", "section"]))
        if action == "value" and "=" in lines[i]:
            key = lines[i].split("=", 1)[0]
            lines[i] = (
                f"{key}={draw(st.sampled_from(['', '0x', '-1', '1e999', 'nan', '0xFFFFFFFFFFFF', '$NODEID+', 'x']))}"
            )
        elif action == "drop":
            del lines[i]
        elif action == "garbage":
            lines.insert(i, draw(st.text(max_size=20)))
        else:
            lines.insert(i, f"[{draw(st.sampled_from(['1000', 'ZZZZ', '6041sub', '', '2000sub99']))}]")
    raw = "\n".join(lines).encode("utf-8", errors="replace")
    if draw(st.booleans()):
        raw = raw[: draw(st.integers(0, len(raw)))]
    return raw


COLUMNS = ["time_s", "y_position_rad", "y_torque_Nm", "y_valid", "x_position_m", "x_force_N", "junk", ""]
NUMBER = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True, width=64),
    st.integers(-(10**12), 10**12),
    st.sampled_from(["", "nan", "x", "1e400", "--"]),
)


@st.composite
def csv_logs(draw) -> str:
    """Small CSV logs: plausible headers with hostile rows, or a plausible log with damage."""
    if draw(st.booleans()):
        header = draw(st.lists(st.sampled_from(COLUMNS), min_size=0, max_size=6))
        rows = draw(st.lists(st.lists(NUMBER, min_size=0, max_size=7), max_size=40))
        return ",".join(header) + "\n" + "\n".join(",".join(map(str, r)) for r in rows)
    n = draw(st.integers(2, 400))
    dt = draw(st.sampled_from([0.001, 0.002, 0.0021, 1e-9, 0.0]))
    rows = [f"{k * dt:.9g},{math.sin(k / 20):.6g},{0.3 * math.cos(k / 20):.6g}" for k in range(n)]
    for _ in range(draw(st.integers(0, 3))):
        k = draw(st.integers(0, n - 1))
        rows[k] = ",".join(str(draw(NUMBER)) for _ in range(draw(st.integers(1, 4))))
    return "time_s,y_position_rad,y_torque_Nm\n" + "\n".join(rows)


JSON = st.recursive(
    st.one_of(st.none(), st.booleans(), st.integers(-(2**70), 2**70), st.floats(), st.text(max_size=6)),
    lambda inner: st.one_of(
        st.lists(inner, max_size=4), st.dictionaries(st.text(max_size=6), inner, max_size=4)
    ),
    max_leaves=12,
)
NAMES = st.sampled_from(
    [
        "J",
        "c0",
        "c1",
        "KpS",
        "KpP",
        "KiS",
        "KpC",
        "KiC",
        "FwF",
        "ff_enable",
        "offset",
        "periodic_period",
        "periodic_amplitude",
        "cp",
        "dc1",
    ]
)


@st.composite
def result_files(draw, kind: str) -> str:
    """identify.json or tune.json: hostile JSON, or the right shape with hostile values."""
    shape = draw(st.integers(0, 4))
    if shape == 0:
        return json.dumps(draw(JSON))
    if shape == 1:  # nested deeper than any parser recurses
        depth = draw(st.integers(500, 5000))
        return '{"axes": ' + "[" * depth + "]" * depth + "}"
    field_ = "params" if kind == "identify" else "parameters"
    axes = draw(
        st.dictionaries(
            st.sampled_from(["x", "y", "z", "w", ""]),
            st.fixed_dictionaries(
                {
                    field_: st.one_of(
                        st.dictionaries(
                            NAMES,
                            st.one_of(
                                st.floats(),
                                st.integers(-(10**40), 10**40),
                                st.text(max_size=3),
                                st.sampled_from([10**400, -(10**400)]),
                            ),
                            max_size=8,
                        ),
                        st.fixed_dictionaries(
                            {
                                "J": st.floats(1e-7, 1e-2),
                                "c0": st.floats(0.0, 2.0),
                                "c1": st.floats(0.0, 1e-2),
                            },
                            optional={"KpS": st.floats(1e-3, 1.0)},
                        ),
                    ),
                    "motor": st.one_of(
                        st.none(), st.fixed_dictionaries({"R": st.floats(), "L": st.floats()})
                    ),
                }
            ),
            max_size=3,
        )
    )
    return json.dumps({"axes": axes})


@dataclass
class Kind:
    """One kind of input: how to make it and the reader it goes through."""

    name: str
    strategy: st.SearchStrategy
    read: Callable[[object, Path], object]


def _write(tmp: Path, name: str, content) -> Path:
    path = tmp / name
    if isinstance(content, bytes):
        path.write_bytes(content)
    else:
        path.write_text(content, encoding="utf-8")
    return path


def _bus_yml(text, tmp: Path):
    path = _write(tmp, "bus.yml", text)
    eds_dir = tmp.parent / "eds"
    if not eds_dir.exists():
        shutil.copytree(PROJECT_EDS.parent, eds_dir, dirs_exist_ok=True)
    return load_bus_config(path)


def _sim_yaml(text, tmp: Path):
    return load_sim_config(_write(tmp, "robot.yaml", text))


def _eds(raw, tmp: Path):
    return load_od(_write(tmp, "drive.eds", raw), 1)


def _profile(text, tmp: Path):
    return load_profile(_write(tmp, "drive.yaml", text))


def _csv(text, tmp: Path):
    return read_log(_write(tmp, "log.csv", text))


def _identify_json(text, tmp: Path):
    models = read_identify_json(_write(tmp, "identify.json", text))
    return tune(models, {a: {"motor": {"R": 0.8, "L": 0.002}, "parameters_before": {}} for a in models})


def _tune_json(text, tmp: Path):
    tuned = read_tune_json(_write(tmp, "tune.json", text))
    profile = load_profile("drive_bridge_servo")
    od = load_od(PROJECT_EDS, 1)
    return [check_set(profile, od, v) for v in tuned.parameters.values()]


def _trace(raw, tmp: Path):
    """A damaged copy of a real trace (``raw`` is (trace bytes, meta text))."""
    trace, meta = raw
    _write(tmp, "meta.yaml", meta)
    return decode_trace(_write(tmp, "trace.blf", trace))


@st.composite
def damaged_traces(draw, trace: bytes, meta: str):
    data = bytearray(trace)
    action = draw(st.sampled_from(["truncate", "flip", "both", "meta"]))
    if action in ("truncate", "both"):
        data = data[: draw(st.integers(0, len(data)))]
    if action in ("flip", "both") and data:
        for _ in range(draw(st.integers(1, 8))):
            i = draw(st.integers(0, len(data) - 1))
            data[i] = draw(st.integers(0, 255))
    if action == "meta":
        return bytes(data), draw(mutated_yaml(yaml.safe_load(meta)))
    return bytes(data), meta


ARGV = st.lists(
    st.sampled_from(
        [
            "--seed",
            "-1",
            "nan",
            "inf",
            "--cutoff",
            "--decimate",
            "0",
            "1e309",
            "--axis",
            "--out",
            "--json",
            "--validate",
            "x",
            "",
            "--sim",
            "--realtime",
            "--steps",
            "identify,nope",
            "--min-phase-margin",
            "--force",
            "--profile",
            "nope",
        ]
    ),
    max_size=6,
)


def _cli(argv, tmp: Path):
    """A command with hostile values; argparse's own refusal (SystemExit 2) is a clean refusal too."""
    log = tmp / "empty.csv"
    log.write_text("time_s,y_position_rad,y_torque_Nm\n")
    (tmp / "file").write_text("x")
    argv = [str(tmp / "file") if a == "x" else a for a in argv]
    for command in (
        ["identify", str(log)],
        ["tune", "--ident", str(tmp / "file"), "--offline"],
        ["decode", str(tmp / "file")],
    ):
        try:
            code = main(command + argv)
        except SystemExit as exc:
            code = exc.code
        if code not in (0, 2, 3):
            raise AssertionError(f"{command + argv}: exit {code}")


def record_trace(out: Path) -> tuple[bytes, str]:
    """A real trace and its meta.yaml: a short lockstep recording of one axis, in ``out``."""
    from drive_bridge.recorder import record

    from .support import Bench, clean_config, quick_config

    bench = Bench(clean_config())
    try:
        record(quick_config(max_axis_time_s=1.0).only(["y"]), bench.link, out)
    finally:
        bench.close()
    return (out / "trace.blf").read_bytes(), (out / "meta.yaml").read_text()


def _bus_base() -> dict:
    """The shipped bus.yml with every per-node option in use: Z homes first, Y's stroke is laid out
    around where it stands."""
    doc = yaml.safe_load(DEFAULT_BUS_CONFIG.read_text())
    doc["nodes"]["z"].update(
        reference="home", homing={"method": 17, "switch_speed_m_s": 0.01, "timeout_s": 60}
    )
    doc["nodes"]["y"]["reference"] = "here"
    return doc


def kinds(trace: bytes | None = None, meta: str | None = None) -> dict[str, Kind]:
    """Every kind of input (the trace kind only when a real trace and its meta.yaml are given)."""
    out = [
        Kind("bus.yml", mutated_yaml(_bus_base()), _bus_yml),
        Kind("simulator YAML", mutated_yaml(yaml.safe_load(SIM_CONFIG.read_text())), _sim_yaml),
        Kind("EDS/DCF", mutated_eds(), _eds),
        Kind(
            "drive profile",
            mutated_yaml(yaml.safe_load((PROFILE_DIR / "drive_bridge_servo.yaml").read_text())),
            _profile,
        ),
        Kind("log CSV", csv_logs(), _csv),
        Kind("identify.json", result_files("identify"), _identify_json),
        Kind("tune.json", result_files("tune"), _tune_json),
        Kind("command line", ARGV, _cli),
    ]
    if trace is not None:
        out.append(Kind("CAN trace", damaged_traces(trace, meta), _trace))
    out.append(IDENTIFY)
    return {k.name: k for k in out}


@st.composite
def plant_logs(draw) -> str:
    """Logs of a rigid axis made here (not by the simulator): J·q̈ + c1·q̇ + c0·sign(q̇) + noise, with
    the motions a campaign log is not -- one speed, one direction, a prefix, a pause, a spike, a
    flat line, a jittered clock."""
    import numpy as np

    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    rate = draw(st.sampled_from([200.0, 500.0, 1000.0]))
    n = int(rate * draw(st.floats(0.3, 8.0)))
    t = np.arange(n) / rate
    shape = draw(st.sampled_from(["sine", "one_speed", "one_way", "still", "two_tones"]))
    amp = draw(st.floats(1e-3, 50.0))
    q = {
        "sine": amp * np.sin(2 * np.pi * 0.5 * t),
        "one_speed": amp * np.abs((t % 2.0) - 1.0),
        "one_way": amp * t,
        "still": np.full(n, amp),
        "two_tones": amp * (np.sin(2 * np.pi * 0.3 * t) + 0.3 * np.sin(2 * np.pi * 2.1 * t)),
    }[shape]
    qd, qdd = np.gradient(q, t), np.gradient(np.gradient(q, t), t)
    tau = (
        1e-4 * qdd
        + 5e-4 * qd
        + 0.3 * np.sign(qd)
        + rng.normal(0, draw(st.sampled_from([0.0, 1e-3, 0.05])), n)
    )
    damage = draw(st.sampled_from(["none", "spike", "nan_run", "jitter", "zero_torque"]))
    if damage == "spike":
        tau[rng.integers(n)] = draw(st.sampled_from([1e6, -1e6, 1e300]))
    elif damage == "nan_run":
        k = int(rng.integers(n))
        tau[k : k + int(rng.integers(1, 200))] = np.nan
    elif damage == "jitter":
        t = t + rng.uniform(-0.3, 0.3, n) / rate
    elif damage == "zero_torque":
        tau[:] = 0.0
    rows = "\n".join(f"{a:.9g},{b:.9g},{c:.9g}" for a, b, c in zip(t, q, tau))
    return "time_s,y_position_rad,y_torque_Nm\n" + rows


def _identify(text, tmp: Path):
    from drive_bridge.ident import identify

    return identify(_write(tmp, "log.csv", text), seed=0)


IDENTIFY = Kind("identify (log)", plant_logs(), _identify)
