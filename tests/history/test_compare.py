"""Each drive against its past and its siblings, on records made by hand: a change is named when it
is beyond noise (combined std) and beyond the threshold, never for an undetermined parameter."""

from __future__ import annotations

import pytest

from drive_bridge.history import History, HistoryStore, compare

from .records import PRODUCT, axis, day, nominal, record


def hall(db: str, rising: float = 1.38, std_scale: float = 1.0) -> HistoryStore:
    """Twelve machines of one type, each Y axis commissioned in spring; in autumn again, and
    machine 5's Y friction has risen by ``rising``."""
    store = HistoryStore(db)
    for m in range(12):
        wobble = 1 + 0.004 * ((m * 7) % 5 - 2)  # the machines differ a little
        for visit, when in enumerate((day(m), day(200 + m))):
            c0 = 0.323 * wobble * (rising if (m == 5 and visit == 1) else 1.0)
            params = {"J": (1.0e-4 * wobble, 5e-7), "c0": (c0, 1.6e-3 * std_scale), "c1": (5.0e-4, 2.5e-6)}
            store.add(record(when, [axis("y", 2000 + m, params), axis("x", 1000 + m, nominal())]))
    return store


def test_the_drive_whose_friction_rose_is_named_in_words_and_no_other(db):
    found = compare(History(hall(db).parameters()))
    named = [c for c in found if c.named]
    assert [(c.serial, c.axis, c.name) for c in named] == [(2005, "y", "c0")]
    c = named[0]
    assert c.changed and c.stands_out
    assert c.relative == pytest.approx(0.38, rel=1e-6) and c.sigmas > 20 and c.siblings == 11
    assert c.words().startswith("serial 2005, axis y: c0 +38 % (")
    assert "σ) since 2026-03-07 and" in c.words() and "spread above its 11 siblings" in c.words()


def test_noise_is_not_news_a_large_change_within_its_std_is_not_named(db):
    found = compare(History(hall(db, rising=1.38, std_scale=80).parameters()))  # std 0.13 Nm: 38 % is < 1 σ
    c = next(c for c in found if c.serial == 2005 and c.name == "c0")
    assert abs(c.sigmas) < 3 and not c.changed


def test_a_significant_but_small_change_is_under_the_threshold(db):
    found = compare(History(hall(db, rising=1.05).parameters()))
    c = next(c for c in found if c.serial == 2005 and c.name == "c0")
    assert c.sigmas > 3 and not c.named  # +5 %: below 10 %
    named = compare(History(hall(db, rising=1.05).parameters()), threshold=0.03)
    assert [(c.serial, c.name) for c in named if c.named] == [(2005, "c0")]


def test_filters_an_undetermined_parameter_and_siblings_of_another_type(db):
    store = HistoryStore(db)
    for n in range(4):
        store.add(record(day(n), [axis("y", 7, {"J": (1e-4, 5e-7), "c1": (2e-4 * (1 + n), 1e-3, False)})]))
        store.add(record(day(n), [axis("y", 70 + n, {"J": (3e-4, 5e-7)}, product=PRODUCT + 1)]))
    found = compare(History(store.parameters()), serial=7)
    assert [c.name for c in found] == ["J"]  # c1 undetermined: never compared
    assert found[0].siblings == 0  # the other product is no sibling
    assert compare(History(store.parameters()), axis="x") == []


def test_an_identification_of_a_log_names_no_drive_and_is_not_compared(db):
    store = HistoryStore(db)
    store.add(record(day(0), [axis("y", None, nominal())]))
    store.add(record(day(1), [axis("y", None, nominal(2.0))]))
    assert len(store.runs()) == 2 and compare(History(store.parameters())) == []


def test_simulated_runs_are_compared_with_simulated_runs_only(db):
    store = HistoryStore(db)
    store.add(record(day(0), [axis("y", 9, nominal())]))
    store.add(record(day(1), [axis("y", 9, nominal(2.0))], simulated=True))
    assert all(c.previous is None for c in compare(History(store.parameters())))
