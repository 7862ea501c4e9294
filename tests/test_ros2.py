"""ros2_canopen's bus.yml, read as it is and written for ros2_canopen and Lely's dcfgen."""

from __future__ import annotations

import subprocess

import pytest
import yaml

from drive_bridge.cli import main
from drive_bridge.config import load_bus_config
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
    assert "nodes: boot, driver, heartbeat_consumer, package, period, position_mode" in err
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
