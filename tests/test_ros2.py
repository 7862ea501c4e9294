"""ros2_canopen's bus.yml, read as it is and written for ros2_canopen and Lely's dcfgen."""

from __future__ import annotations

import json
import math
import subprocess

import pytest
import yaml

from drive_bridge.cli import main
from drive_bridge.config import load_bus_config
from drive_bridge.errors import ConfigError
from drive_bridge.resources import DEFAULT_BUS_CONFIG, data
from harness.support import EDS, tool

pytestmark = [pytest.mark.slow, pytest.mark.third_party]

ROS2 = data("config", "ros2_canopen.yml")


def test_a_ros2_canopen_bus_yml_is_read_as_it_is(tmp_path, capsys):
    """The shipped example in ros2_canopen's format (options, master node-ID and baudrate, driver
    and package, defaults, PDOs with enabled / cob_id auto / transmission 0xFF / event_timer):
    the same node setup as drive-bridge's own bus.yml, and one note per section of what is ignored."""
    ros, own = load_bus_config(ROS2), load_bus_config(DEFAULT_BUS_CONFIG)
    assert ros.master.node_id == 127 and ros.master.bitrate == 1_000_000
    for axis, n in own.nodes.items():
        r = ros.nodes[axis]
        assert (r.node_id, r.scaling, r.limits) == (n.node_id, n.scaling, n.limits)
        assert [(p.number, p.transmission, p.mapping) for p in r.tpdo] == [
            (p.number, p.transmission, p.mapping) for p in n.tpdo
        ]
        assert r.tpdo[1].event_timer_ms == 0
        assert r.rpdo[0].mapping == n.rpdo[0].mapping and r.rpdo[0].transmission == 0xFF
    assert (
        main(["record", "--sim", "--quick", "--axes", "y", "--config", str(ROS2), "--out", str(tmp_path)])
        == 0
    )
    err = capsys.readouterr().err
    assert "master: driver, package (ros2_canopen / Lely keys" in err  # heartbeat_producer is the master's
    assert ros.master.heartbeat_period_s == 0.1
    assert (
        "nodes: boot, driver, heartbeat_consumer, package, sdo_timeout_ms (" in err
    )  # period, position_mode honoured
    assert ros.nodes["x"].scaling.increments_per_rev == 2**20  # from x's scale_pos_to_dev [increments/m]
    assert main(["decode", str(tmp_path / "trace.blf"), "--out", str(tmp_path / "d.csv")]) == 0
    assert (tmp_path / "d.csv").read_bytes() == (tmp_path / "log.csv").read_bytes()


def _ros2_doc() -> dict:
    return yaml.safe_load(ROS2.read_text())


def _write(tmp_path, doc) -> str:
    path = tmp_path / "bus.yml"
    doc.setdefault("options", {})["dcf_path"] = str(EDS.parent)
    path.write_text(yaml.safe_dump(doc))
    return str(path)


def test_defaults_replace_node_entries_as_ros2_canopen_merges_and_the_note_says_so(tmp_path, capsys):
    doc = _ros2_doc()
    doc["defaults"]["heartbeat_producer"] = 50
    doc["nodes"]["x"]["heartbeat_producer"] = 200  # ros2_canopen's cogen writes defaults over it
    cfg = load_bus_config(_write(tmp_path, doc))
    assert cfg.nodes["x"].heartbeat_producer_ms == 50
    assert any(
        "nodes.x: heartbeat_producer replaced by defaults (ros2_canopen's merge order" in n
        for n in cfg.master.notes
    )


def test_the_older_layout_with_slaves_at_the_top_level(tmp_path):
    doc = _ros2_doc()
    defaults = doc.pop("defaults")
    for axis, node in doc.pop("nodes").items():
        doc[axis] = {**node, **defaults}
    cfg = load_bus_config(_write(tmp_path, doc))
    assert sorted(cfg.nodes) == ["x", "y", "z"] and cfg.nodes["z"].node_id == 3


@pytest.mark.parametrize(
    "pdo,change,message",
    [
        (
            "tpdo",
            {"transmission": 0xFF},
            "tpdo.1.transmission: 0xFF is not synchronous: the master logs one sample",
        ),
        ("rpdo", {"transmission": 0xF5}, "rpdo.1.transmission: 0xF5 is reserved by CiA 301 for a RPDO"),
        ("tpdo", {"cob_id": 0x7FF}, "tpdo.1.cob_id: must be 'auto' or an 11-bit PDO COB-ID"),
    ],
)
def test_pdo_settings_the_master_cannot_stream_with_are_one_message(tmp_path, capsys, pdo, change, message):
    doc = _ros2_doc()
    doc["defaults"][pdo][1].update(change)
    path = _write(tmp_path, doc)
    assert main(["scan", "--sim", "--config", path]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err


def test_export_ros2_round_trips_and_lely_dcfgen_takes_it(tmp_path, capsys):
    """export ros2: bus.yml (ros2_canopen's format, no defaults) and one DCF per node. Read back,
    it is the same node setup; Lely's dcfchk passes the DCFs; expanded as ros2_canopen's cogen does,
    dcfgen -r writes the master DCF with its node-ID and bitrate, and the slaves' boot
    configuration enables TPDO2 and writes drive-bridge's bring-up values."""
    out = tmp_path / "ros2"
    assert main(["export", "ros2", "--out", str(out)]) == 0
    text = (out / "bus.yml").read_text()
    assert "defaults" not in text and "index: 0x6040" in text
    assert "inhibit_time: 0" in text and "index: 0x1016" in text  # as bring-up writes them
    own, back = load_bus_config(DEFAULT_BUS_CONFIG), load_bus_config(out / "bus.yml")
    assert (back.master.heartbeat_period_s, back.master.drive_consumer_ms) == (
        own.master.heartbeat_period_s,
        own.master.drive_consumer_ms,
    )
    for axis, n in own.nodes.items():
        b = back.nodes[axis]
        assert (
            b.rpdo,
            b.tpdo,
            b.scaling,
            b.limits,
            b.heartbeat_producer_ms,
            b.following_error_window_rad,
            b.drive_limits,
        ) == (
            n.rpdo,
            n.tpdo,
            n.scaling,
            n.limits,
            n.heartbeat_producer_ms,
            n.following_error_window_rad,
            n.drive_limits,
        )
    assert main(["scan", "--sim", "--config", str(out / "bus.yml")]) == 0  # the simulator knows the DCFs
    if tool("dcfchk"):
        for axis, n in own.nodes.items():
            r = subprocess.run(
                [tool("dcfchk"), "-n", str(n.node_id), str(out / f"{axis}.dcf")],
                capture_output=True,
                text=True,
            )
            assert r.returncode == 0 and "Warning" not in r.stderr, r.stderr
    if tool("dcfgen"):
        doc = yaml.safe_load(text)  # ros2_canopen's cogen: defaults over nodes, nodes to the top
        flat = {"options": doc["options"], "master": doc["master"], **doc["nodes"]}
        (out / "expanded.yml").write_text(yaml.safe_dump(flat))
        (out / "gen").mkdir()
        r = subprocess.run(
            [tool("dcfgen"), "-r", "-v", "-d", "gen", "expanded.yml"], cwd=out, capture_output=True, text=True
        )
        assert r.returncode == 0, r.stderr
        master = (out / "gen" / "master.dcf").read_text()
        assert "NodeID=127" in master and "Baudrate=1000" in master
        # the master produces the heartbeat each drive's consumer (0x1016:1, in its sdo) watches
        assert (
            "[1017]\nParameterName=Producer heartbeat time\nDataType=0x0006\nAccessType=rw\nDefaultValue=100"
            in master
        )
        assert "x: writing 4 bytes to 0x1801/1: 81 02 00 00" in r.stdout  # TPDO2 enabled
        assert (
            "x: writing 4 bytes to 0x6065/0" in r.stdout
            and "x: writing 2 bytes to 0x1017/0: 64 00" in r.stdout
        )


def test_ros2_canopens_cia402_mapping_streams(tmp_path):
    """ros2_canopen's CiA 402 example maps the mode of operation and a target velocity into its
    RPDOs and the mode display into a TPDO: the master fills the mode it streams in and zero,
    logs the mode display, and the identification reads the log (with the torque drive-bridge
    needs mapped too)."""
    doc = _ros2_doc()
    doc["defaults"]["rpdo"] = {
        1: {
            "enabled": True,
            "cob_id": "auto",
            "mapping": [{"index": 0x6040, "sub_index": 0}, {"index": 0x6060, "sub_index": 0}],
        },
        2: {
            "enabled": True,
            "cob_id": "auto",
            "mapping": [{"index": 0x607A, "sub_index": 0}, {"index": 0x60FF, "sub_index": 0}],
        },
    }
    doc["defaults"]["tpdo"] = {
        1: {
            "enabled": True,
            "cob_id": "auto",
            "transmission": 1,
            "mapping": [
                {"index": 0x6041, "sub_index": 0},
                {"index": 0x6061, "sub_index": 0},
                {"index": 0x6077, "sub_index": 0},
            ],
        },
        2: {
            "enabled": True,
            "cob_id": "auto",
            "transmission": 1,
            "mapping": [{"index": 0x6064, "sub_index": 0}, {"index": 0x606C, "sub_index": 0}],
        },
    }
    path = _write(tmp_path, doc)
    out = tmp_path / "rec"
    assert main(["record", "--sim", "--quick", "--axes", "y", "--config", path, "--out", str(out)]) == 0
    header = (out / "log.csv").read_text().splitlines()[0].split(",")
    rows = [r.split(",") for r in (out / "log.csv").read_text().splitlines()[1:]]
    mode = header.index("y_mode_display")
    assert {r[mode] for r in rows if r[mode] != "nan"} == {"8"}  # cyclic synchronous position
    assert main(["identify", str(out), "--json"]) == 0


#: a bus.yml as ros2_canopen's users write it for a CiA 402 drive (its cia402 examples): the EDS
#: beside it through ros2_canopen's @BUS_CONFIG_PATH@, scale_pos/vel_to_dev and _from_dev, the
#: PDOs ros2_canopen's Cia402Driver needs (statusword, mode display, position, velocity; controlword,
#: mode, target) -- nothing of drive-bridge's own: no scaling, limits, torque in a TPDO, campaign
AS_ROS2_USERS_WRITE_IT = """
options:
  dcf_path: "@BUS_CONFIG_PATH@"
master:
  node_id: 127
  driver: "ros2_canopen::MasterDriver"
  package: "canopen_master_driver"
  sync_period: 2000
defaults:
  dcf: "drive_bridge_servo.eds"
  driver: "ros2_canopen::Cia402Driver"
  package: "canopen_402_driver"
  period: 2
  heartbeat_producer: 100
  position_mode: 8
  scale_pos_to_dev: 166886.05
  scale_pos_from_dev: 0.0000059921
  scale_vel_to_dev: 166886.05
  scale_vel_from_dev: 0.0000059921
  sdo:
    - {index: 0x60C2, sub_index: 1, value: 2}
    - {index: 0x60C2, sub_index: 2, value: -3}
  tpdo:
    1:
      enabled: true
      cob_id: "auto"
      transmission: 0x01
      mapping:
        - {index: 0x6041, sub_index: 0}
        - {index: 0x6061, sub_index: 0}
    2:
      enabled: true
      cob_id: "auto"
      transmission: 0x01
      mapping:
        - {index: 0x6064, sub_index: 0}
        - {index: 0x606C, sub_index: 0}
  rpdo:
    1:
      enabled: true
      cob_id: "auto"
      mapping:
        - {index: 0x6040, sub_index: 0}
        - {index: 0x6060, sub_index: 0}
    2:
      enabled: true
      cob_id: "auto"
      mapping:
        - {index: 0x607A, sub_index: 0}
nodes:
  x: {node_id: 1}
  y: {node_id: 2}
  z: {node_id: 3}
"""


def test_a_bus_yml_as_ros2_canopens_users_write_it_scans_and_commissions(tmp_path, capsys):
    """Nothing of drive-bridge's own in it: its scale_pos/vel_to_dev are the units (checked against
    what the drive reports), the rated torque is the drive's 0x6076, the limits the drive's (0x607D,
    0x607F, 0x6083/0x6084: the simulated machine's integrator left them there), the torque added to
    a TPDO with room, each said with its value; then scan and commission run on the simulated
    robot, within the limits the drive holds."""
    bus = _as_ros2_users_write_it(tmp_path)
    config = load_bus_config(bus)
    x = config.nodes["x"]
    assert x.limits_from_drive and x.position_mode == 8
    # five significant digits, as people write them: 1/166886.05 is 5.99211e-06 (2.1e-6 apart), the
    # _to_dev is the one used, and the run says so
    assert x.scaling.increments_per_rev == pytest.approx(2**20, rel=1e-6)
    assert x.scaling.velocity_per_rad_s == pytest.approx(2**20 / 6.283185307, rel=1e-6)
    assert "nodes.x.scale_pos_from_dev 5.9921e-06 is 1/scale_pos_to_dev to 2.1e-06 relative" in " ".join(
        config.master.notes
    )
    assert x.tpdo[0].mapping == ((0x6041, 0), (0x6061, 0), (0x6077, 0))  # the torque where it fits
    assert "nodes.x.tpdo: 0x6077 to TPDO 1" in " ".join(config.master.notes)
    assert main(["scan", "--sim", "--config", str(bus)]) == 0
    out = tmp_path / "run"
    args = [
        "commission",
        "--sim",
        "--config",
        str(bus),
        "--campaign",
        "short",
        "--no-history",
        "--no-figures",
    ]
    assert main([*args, "--yes", "--out", str(out)]) in (0, 3)  # PASS or WARN: it ran to its end
    err = capsys.readouterr().err
    assert "axis x: no limits in" in err and "stroke -13.09 .. 13.09 rad (0x607D)" in err
    assert "max velocity 8.3776 rad/s (1/1.25 of 0x607F)" in err  # the default bus.yml's 0.08 m/s
    summary = json.loads((out / "summary.json").read_text())
    assert [step["status"] for step in summary["steps"]] == ["done"] * len(summary["steps"])
    bringup = json.loads((out / "bringup.json").read_text())
    written = bringup["axes"]["x"]["process_data"]["drive_limits"]  # as read back
    assert written["0x607D:2"] == round(13.09 * 2**20 / (2 * math.pi))  # what it held, kept


@pytest.mark.parametrize(
    "change, key, words",
    [
        ({"position_mode": 1}, "position_mode", "drive-bridge streams its setpoints"),
        ({"period": 10}, "period", "sends a setpoint with every SYNC"),
        (
            {"scale_pos_from_dev": 1e-3},
            "scale_pos_from_dev",
            "1/166886.05 = 5.99211e-06 (they differ by 1.7e+02",
        ),
        (
            {"scale_vel_from_dev": 5.9932e-06},
            "scale_vel_from_dev",
            "more than 0.0001): ros2_canopen commands",
        ),
        ({"scale_vel_to_dev": -1.0}, "scale_vel_to_dev", "above 0"),
    ],
)
def test_a_ros2_canopen_key_drive_bridge_cannot_honour_is_one_message(tmp_path, change, key, words):
    """A ros2_canopen key is honoured or refused naming the key, never silently ignored: a
    position_mode drive-bridge cannot stream in, a setpoint period not the SYNC's, scales that are
    not each other's inverse or not positive."""
    (tmp_path / "drive_bridge_servo.eds").write_bytes(EDS.read_bytes())
    doc = yaml.safe_load(AS_ROS2_USERS_WRITE_IT)
    doc["defaults"].update(change)
    bus = tmp_path / "bus.yml"
    bus.write_text(yaml.safe_dump(doc))
    with pytest.raises(ConfigError) as refused:
        load_bus_config(bus)
    assert f"nodes.x.{key}" in str(refused.value) and words in str(refused.value)


def _as_ros2_users_write_it(tmp_path) -> str:
    (tmp_path / "drive_bridge_servo.eds").write_bytes(EDS.read_bytes())
    bus = tmp_path / "bus.yml"
    bus.write_text(AS_ROS2_USERS_WRITE_IT)
    return str(bus)


def test_without_limits_in_bus_yml_or_in_the_drive_nothing_moves(tmp_path, capsys):
    """The same bus.yml on a machine whose drives hold no software position limits (the compliant
    simulated robot: factory values, 0x607D 0..0): nothing says how far the axis may travel, so
    the run is refused at bring-up, naming the object and both ways out -- and no axis moved."""
    bus = _as_ros2_users_write_it(tmp_path)
    args = ["record", "--sim", "--sim-config", "compliant", "--quick", "--axes", "y", "--config", bus]
    assert main([*args, "--yes", "--out", str(tmp_path / "run")]) != 0
    err = capsys.readouterr().err
    assert "the drive holds no stroke (software position limits 0x607D)" in err
    assert "give nodes.y.limits" in err
    assert not (tmp_path / "run" / "log.csv").exists()


def test_a_jog_faster_than_the_limit_the_drive_holds_is_refused(tmp_path, capsys):
    """--speed is judged against the limit bring-up read from the drive (x: 0x607F/1.25 = 8.38 rad/s),
    not against the no-motion placeholder the bus.yml leaves until then."""
    bus = _as_ros2_users_write_it(tmp_path)
    assert main(["jog", "x", "--sim", "--config", bus, "--by", "0.5", "--speed", "9.0", "--yes"]) != 0
    assert "within the axis's limit 8.378 rad/s" in capsys.readouterr().err
