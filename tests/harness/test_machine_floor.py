"""The machine's floor (harness/machine_floor.py) judges a stall that stopped a wall-clock run: the
machine's, where a plain loop beside it was held up as long, and the run goes again; else ours, and
the test fails saying both."""

from __future__ import annotations

import contextlib
import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from harness import machine_floor
from harness.machine_floor import PERIOD_S, Floor, beside_the_floor, machine_explains


def next_sync(awake: float) -> float:
    """When the engine (``master/engine.py``'s ``_cycle``) sends the SYNC due one period after the
    last, at 0, where it woke only at ``awake`` [s]: the missed periods get none, and the next goes
    out at the period nearest its wake-up (waited for where it is still ahead)."""
    deadline = PERIOD_S
    late = awake - deadline
    while late > PERIOD_S / 2:
        deadline += max(1, round(late / PERIOD_S)) * PERIOD_S
        late = awake - deadline
    return max(awake, deadline)


@settings(max_examples=500, deadline=None, database=None, derandomize=True)
@given(
    began=st.floats(0.0, PERIOD_S, exclude_max=True),  # after the engine's last SYNC [s]
    lasted=st.floats(0.0, 0.1),  # [s]
    phase=st.floats(0.0, PERIOD_S, exclude_max=True),  # of the plain loop's schedule [s]
)
def test_a_stall_of_the_machine_explains_every_sync_gap_it_makes(began, lasted, phase):
    """The machine stops every task for ``lasted`` from ``began``: whatever the phases, the plain
    loop's lateness explains the SYNC gap the engine's schedule makes of it."""
    gap = next_sync(max(PERIOD_S, began + lasted))
    deadline = phase + math.ceil((began - phase) / PERIOD_S) * PERIOD_S  # the loop's first after it began
    held = max(0.0, began + lasted - deadline)
    assert machine_explains(gap * 1e3, held * 1e3), (gap, held)


@contextlib.contextmanager
def _floor_held(held_ms: list[float]):
    """A floor whose plain loop was held up the next of ``held_ms`` [ms] in this attempt."""
    yield Floor(held=[[(0.0, held_ms.pop(0))]])


def test_a_stall_the_floor_did_not_show_is_ours_and_fails_saying_both(monkeypatch):
    """A 24 ms SYNC gap beside a loop held up 12 ms: ours, however often it would run again."""
    monkeypatch.setattr(machine_floor, "floor_during", lambda: _floor_held([12.0, 12.0, 12.0]))
    runs = []
    with pytest.raises(
        AssertionError, match="a stall of ours stopped the run: a 24 ms stall, the floor held 12 ms"
    ):
        beside_the_floor(lambda: runs.append(1), lambda _: 24.0)
    assert len(runs) == 1


def test_a_stall_the_floor_showed_runs_again_and_only_so_often(monkeypatch):
    """A 24 ms SYNC gap beside a loop held up 21 ms (the machine's, within 2.5 periods): the run
    goes again, and its outcome stands where no stall stopped it; three such stalls fail the test."""
    monkeypatch.setattr(machine_floor, "floor_during", lambda: _floor_held([21.0, 0.1]))
    outcomes = iter([("stalled", 24.0), ("ok", None)])
    assert beside_the_floor(lambda: next(outcomes), lambda run: run[1]) == ("ok", None)
    monkeypatch.setattr(machine_floor, "floor_during", lambda: _floor_held([21.0, 22.0, 23.0]))
    with pytest.raises(AssertionError, match="the machine stalled the run in each of 3 attempts"):
        beside_the_floor(lambda: None, lambda _: 24.0)
