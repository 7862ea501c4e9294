"""Which bus: the command line, bus.yml, then python-can's own configuration, as its tools do."""

from __future__ import annotations

import pytest

from drive_bridge.canconf import resolve
from drive_bridge.cli import main
from drive_bridge.config import load_bus_config
from harness.support import BUS_CONFIG, bus_yml_beside

NO_INTERFACE = (
    "  interface: virtual          # socketcan / pcan / kvaser ... on a real bus\n"
    "  channel: drive-bridge\n  bitrate: 1000000\n"
)


@pytest.fixture
def canrc(tmp_path, monkeypatch):
    """A home whose ~/.canrc python-can reads, and no CAN_* environment."""
    for name in ("CAN_INTERFACE", "CAN_CHANNEL", "CAN_BITRATE", "CAN_CONFIG"):
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setenv("HOME", str(tmp_path))

    def write(text: str):
        (tmp_path / ".canrc").write_text(text)

    return write


def test_python_cans_configuration_fills_what_bus_yml_leaves_out(tmp_path, canrc):
    assert NO_INTERFACE in BUS_CONFIG.read_text()
    canrc(
        "[default]\ninterface = virtual\nchannel = 0\nbitrate = 250000\nreceive_own_messages = True\n"
        "app_name = CANalyzer\n"
    )
    cfg = resolve(load_bus_config(bus_yml_beside(tmp_path, NO_INTERFACE, "")))
    m = cfg.master
    assert (m.interface, m.channel, m.bitrate) == ("virtual", 0, 250000)  # an integer channel, as kvaser's
    assert m.can_options == {"app_name": "CANalyzer", "receive_own_messages": False}
    notes = " | ".join(m.notes)
    assert "from python-can's configuration" in notes and "receive_own_messages = True" in notes
    assert "app_name = 'CANalyzer' from python-can's configuration, passed to the bus" in notes
    assert m.nominal_bitrate == 250000


def test_the_command_line_comes_first_then_bus_yml_then_the_environment(tmp_path, canrc, monkeypatch):
    canrc("[default]\ninterface = pcan\nchannel = PCAN_USBBUS1\n")
    monkeypatch.setenv("CAN_BITRATE", "500000")
    base = load_bus_config(BUS_CONFIG)
    m = resolve(base).master
    assert (m.interface, m.channel, m.bitrate) == (
        "virtual",
        "drive-bridge",
        1_000_000,
    )  # bus.yml over python-can
    m = resolve(base, "socketcan", "can1", 125000).master
    assert (m.interface, m.channel, m.bitrate) == ("socketcan", "can1", 125000)
    assert any("from the command line" in n for n in m.notes)
    m = resolve(load_bus_config(bus_yml_beside(tmp_path, NO_INTERFACE, ""))).master
    assert (m.interface, m.channel, m.bitrate) == ("pcan", "PCAN_USBBUS1", 500000)


def test_interface_options_pass_through_and_an_unknown_interface_is_named(tmp_path, canrc, capsys):
    canrc("")
    cfg = bus_yml_beside(
        tmp_path, NO_INTERFACE, "  interface: virtual\n  channel: 7\n  can_options: {rx_queue_size: 64}\n"
    )
    m = resolve(load_bus_config(cfg)).master
    assert m.channel == 7 and m.can_options == {"rx_queue_size": 64, "receive_own_messages": False}
    (tmp_path / "b").mkdir()
    bad = bus_yml_beside(tmp_path / "b", NO_INTERFACE, "  interface: warp-drive\n  channel: 0\n")
    assert main(["scan", "--config", str(bad)]) == 2
    err = capsys.readouterr().err
    assert "master.interface: python-can refuses it" in err and "warp-drive" in err and "Traceback" not in err


def test_no_interface_anywhere_is_one_message(tmp_path, canrc, capsys):
    canrc("")
    cfg = bus_yml_beside(tmp_path, NO_INTERFACE, "")
    assert main(["scan", "--config", str(cfg)]) == 2
    err = capsys.readouterr().err
    assert "no CAN interface named" in err and "-i/--interface" in err and "CAN_INTERFACE" in err
    assert main(["scan", "--sim", "--config", str(cfg)]) == 0  # the simulated robot needs none


def test_the_command_line_opens_the_bus_it_names(tmp_path, canrc, capsys):
    """-i/-c on a bus.yml without interface: the master opens that bus (here an empty virtual bus:
    nobody answers, exit 3 naming the bus)."""
    canrc("")
    cfg = bus_yml_beside(tmp_path, NO_INTERFACE, "")
    assert main(["scan", "--config", str(cfg), "-i", "virtual", "-c", "empty-bus-42"]) == 3
    err = capsys.readouterr().err
    assert (
        "virtual:empty-bus-42" in err
        and "interface 'virtual', channel 'empty-bus-42' from the command line" in err
    )
