"""The genetic algorithm's solver: scipy's differential evolution with a generation's donors drawn at once."""

from __future__ import annotations

import numpy as np
from scipy import optimize
from scipy.optimize._differentialevolution import DifferentialEvolutionSolver

from drive_bridge.ident import evolution


def test_donors_are_distinct_other_members_drawn_uniformly():
    rng = np.random.default_rng(3)
    members, rounds = 12, 4000
    candidates = np.arange(members)
    counts = np.zeros((evolution.DONORS, members))
    for _ in range(rounds):
        d = evolution.donors(rng, candidates, members)
        assert d.shape == (members, evolution.DONORS)
        assert not np.any(d == candidates[:, None])  # never the member itself
        assert all(len(set(row)) == evolution.DONORS for row in d.tolist())  # distinct
        assert d.min() >= 0 and d.max() < members
        for k in range(evolution.DONORS):
            np.add.at(counts[k], d[:, k], 1)
    # each position of the tuple takes every member equally often (each member excludes only itself)
    expected = rounds * members / members
    assert np.all(np.abs(counts - expected) < 5 * np.sqrt(expected))


def test_scipy_still_has_the_step_it_replaces():
    # a scipy release without it would run its own (correct, slower) loop: this says when to look again
    assert callable(getattr(DifferentialEvolutionSolver, "_mutate_many", None))
    assert "best1bin" in DifferentialEvolutionSolver._binomial


def test_it_reaches_the_least_squares_optimum_as_scipy_does_and_repeats_with_its_seed():
    rng = np.random.default_rng(1)
    n, p = 4000, 6
    phi = rng.standard_normal((n, p))
    y = phi @ rng.standard_normal(p) + 0.1 * rng.standard_normal(n)
    coef, *_ = np.linalg.lstsq(phi, y, rcond=None)
    resid = y - phi @ coef
    std = np.sqrt(np.diag(float(resid @ resid) / (n - p) * np.linalg.inv(phi.T @ phi)))
    gram, b, yy = phi.T @ phi, phi.T @ y, float(y @ y)
    bounds = list(zip(coef - 10 * std - 0.5 * abs(coef), coef + 10 * std + 0.5 * abs(coef)))

    def sse(theta):
        return yy - 2 * b @ theta + np.einsum("is,ij,js->s", theta, gram, theta)

    options = dict(popsize=30, maxiter=400, tol=1e-10, polish=False)
    ours = evolution.differential_evolution(sse, bounds, 7, **options)
    theirs = optimize.differential_evolution(
        sse, bounds, rng=7, vectorized=True, updating="deferred", **options
    )
    assert ours.success and theirs.success
    assert np.max(np.abs(ours.x - coef) / std) < 1e-2
    assert np.max(np.abs(theirs.x - coef) / std) < 1e-2
    assert abs(ours.nit - theirs.nit) < 0.3 * theirs.nit  # the same search, not a shortcut
    again = evolution.differential_evolution(sse, bounds, 7, **options)
    assert np.array_equal(again.x, ours.x)
