"""A simulated drive as the bus's SYNC producer (CiA 301: 0x1005 bit 30, the cycle period 0x1006,
the counter's overflow value 0x1019), on the wall clock: SYNC on the drives' own grid with its
counter, every SYNC it owes sent across a stall of its own process, and the counter's object
written only while no cycle period runs."""

from __future__ import annotations

import numpy as np
import pytest
from canopen.sdo import SdoAbortedError

from drive_bridge.cia.objects import COB_ID_SYNC, CYCLE_PERIOD, SYNC_COUNTER_OVERFLOW
from drive_bridge.cia.p301 import SYNC_COB_ID, SYNC_PRODUCER

PERIOD = 0.002
START = 1000.0  # [s] the wall-clock time the drives start at (stamps, not sleeps)


def producing(bench, overflow: int = 240):
    """Drive x made the SYNC producer at 2 ms with the counter 1..``overflow``; the robot, on the wall
    clock from ``START``, and the frames it sends (COB-ID, data, the bus time it sent them at)."""
    b = bench()
    node = b.nodes["x"]
    node.sdo[SYNC_COUNTER_OVERFLOW].raw = overflow
    node.sdo[CYCLE_PERIOD].raw = round(PERIOD * 1e6)
    node.sdo[COB_ID_SYNC].raw = SYNC_PRODUCER | SYNC_COB_ID
    robot = b.robot
    sent: list[tuple[int, bytes, float]] = []
    bus_send = robot.send

    def send(cob_id: int, data: bytes) -> None:
        sent.append((cob_id, data, robot.wall_time(robot.time)))
        bus_send(cob_id, data)

    robot.send = send
    robot.clock_from(START)
    return b, robot, sent


def syncs(sent) -> tuple[np.ndarray, np.ndarray]:
    """The SYNCs sent: their counters and times."""
    frames = [(data[0], t) for cob_id, data, t in sent if cob_id == SYNC_COB_ID]
    return np.array([c for c, _ in frames]), np.array([t for _, t in frames])


def test_a_drive_produces_sync_on_its_own_grid_with_the_counter(bench):
    _, robot, sent = producing(bench)
    robot.run_until(START + 1.0)
    counters, times = syncs(sent)
    assert len(counters) == pytest.approx(1.0 / PERIOD, abs=1)
    assert np.allclose(np.diff(times), PERIOD)  # on the grid: one a period, to the tick
    assert counters[0] == 1 and counters.max() == 240
    expected = (np.arange(len(counters)) % 240) + 1  # 1..240, again from 1, none skipped
    assert np.array_equal(counters, expected)


def test_across_a_stall_of_its_own_process_it_sends_every_sync_it_owes(bench):
    """The drives' process held up for 200 ms: when it runs again, the periods it passed each send
    their SYNC, with its counter, in order (stamped at their own time); the drives' periods all ran."""
    _, robot, sent = producing(bench)
    for k in range(1, 101):  # 0.2 s on time, a wake every 2 ms
        robot.run_until(START + k * PERIOD)
    robot.run_until(START + 0.4)  # then nothing for 200 ms: one catch-up
    robot.run_until(START + 0.5)
    counters, times = syncs(sent)
    assert len(counters) == pytest.approx(0.5 / PERIOD, abs=1)
    assert np.array_equal(counters, (np.arange(len(counters)) % 240) + 1)
    assert np.allclose(np.diff(times), PERIOD)


def test_the_counter_is_set_only_while_no_cycle_period_runs(bench):
    b, _, _ = producing(bench)
    node = b.nodes["x"]
    with pytest.raises(SdoAbortedError) as refused:
        node.sdo[SYNC_COUNTER_OVERFLOW].raw = 10
    assert refused.value.code == 0x08000022  # CiA 301: not in the present device state
    node.sdo[CYCLE_PERIOD].raw = 0
    with pytest.raises(SdoAbortedError) as refused:
        node.sdo[SYNC_COUNTER_OVERFLOW].raw = 1  # 1 is no overflow value
    assert refused.value.code == 0x06090030
    node.sdo[SYNC_COUNTER_OVERFLOW].raw = 10
    assert node.sdo[SYNC_COUNTER_OVERFLOW].raw == 10


def test_without_a_counter_sync_is_empty_and_without_a_producer_there_is_none(bench):
    b, robot, sent = producing(bench, overflow=0)
    robot.run_until(START + 0.1)
    frames = [data for cob_id, data, _ in sent if cob_id == SYNC_COB_ID]
    assert len(frames) == pytest.approx(0.1 / PERIOD, abs=1) and all(data == b"" for data in frames)
    b.nodes["x"].sdo[COB_ID_SYNC].raw = SYNC_COB_ID  # bit 30 cleared: no more SYNC
    sent.clear()
    robot.run_until(START + 0.2)
    assert not [1 for cob_id, _, _ in sent if cob_id == SYNC_COB_ID]
