"""The batched BLF trace writer writes the very file python-can's BLFWriter writes (this also pins
the BLFWriter internals drive_bridge.master.blf relies on: run it after raising python-can's bound)."""

from __future__ import annotations

import random

import can
import pytest

from drive_bridge.master.blf import BatchedBLFWriter


def frames(seed: int, count: int) -> list[can.Message]:
    rng = random.Random(seed)
    out = []
    t = 1_700_000_000.1234 + rng.random()
    for k in range(count):
        t += rng.choice((0.0, 1e-6, 0.0005, 0.002))
        kind = rng.random()
        if k == count // 3:
            out.append(
                can.Message(
                    timestamp=t,
                    is_error_frame=True,
                    arbitration_id=0x20000004,
                    dlc=8,
                    data=bytes(8),
                    channel=0,
                )
            )
        elif k == count // 2:
            out.append(
                can.Message(
                    timestamp=t, is_fd=True, bitrate_switch=True, arbitration_id=0x123, data=bytes(range(24))
                )
            )
        else:
            size = rng.randint(0, 8)
            out.append(
                can.Message(
                    timestamp=t,
                    arbitration_id=rng.randint(0, 0x1FFFFFFF) if kind < 0.1 else rng.randint(0, 0x7FF),
                    is_extended_id=kind < 0.1,
                    is_remote_frame=0.1 <= kind < 0.15,
                    dlc=size,
                    data=None if 0.1 <= kind < 0.15 else rng.randbytes(size),
                    is_rx=rng.random() < 0.6,
                    channel=rng.choice((None, 0, 1, "vcan3", "drive-bridge")),
                )
            )
    return out


@pytest.mark.parametrize("count", [0, 5, 7001])
@pytest.mark.parametrize("epoch", [0.0, 1_764_000_000.5])
@pytest.mark.parametrize("container_thread", [False, True], ids=["inline", "container-thread"])
def test_batched_writer_writes_what_blfwriter_writes(tmp_path, count, epoch, container_thread):
    sent = frames(count, count)
    ours = BatchedBLFWriter(tmp_path / "ours.blf", epoch=epoch, container_thread=container_thread)
    theirs = can.BLFWriter(tmp_path / "theirs.blf")
    for msg in sent:
        ours.on_message_received(msg)
        stamped = can.Message(
            **{
                k: getattr(msg, k)
                for k in (
                    "arbitration_id",
                    "is_extended_id",
                    "is_remote_frame",
                    "is_error_frame",
                    "is_fd",
                    "bitrate_switch",
                    "dlc",
                    "is_rx",
                    "channel",
                )
            },
            data=msg.data,
            timestamp=msg.timestamp + epoch,
            check=False,
        )
        theirs.on_message_received(stamped)
    assert ours.file_size() >= 0
    end = sent[-1].timestamp if sent else 1_700_000_000.0
    ours.log_event("end of run", end)
    theirs.log_event("end of run", end + epoch)
    ours.stop()
    theirs.stop()
    assert (tmp_path / "ours.blf").read_bytes() == (tmp_path / "theirs.blf").read_bytes()
    read = list(can.BLFReader(tmp_path / "ours.blf"))
    assert len(read) == count
    if count:
        assert read[-1].timestamp == pytest.approx(sent[-1].timestamp + epoch, abs=1e-6)
