"""scipy's differential evolution with each generation's trial vectors made in a few array operations.

With ``updating="deferred"`` and a vectorised cost, scipy evaluates a whole generation at once but
still draws every member's donors in a Python loop (one shuffle of the population index each):
for the model's genetic algorithm (a population of 30 per coefficient, up to 400 generations)
that loop was two thirds of an identification.  :class:`DonorsAtOnce` keeps scipy's solver --
initialisation, bounds, selection, convergence, result -- and replaces only that step for the
binomial strategies, drawing the donors of every member together with the same distribution
(distinct members other than itself, uniformly at random).  Where a scipy release has no such
step the solver is scipy's own, unchanged.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy.optimize import OptimizeResult
from scipy.optimize._differentialevolution import DifferentialEvolutionSolver

DONORS = 5  # as scipy draws: enough for every strategy (rand2 uses five)


def donors(rng: np.random.Generator, candidates: np.ndarray, members: int, k: int = DONORS) -> np.ndarray:
    """Donors for every member at once.

    Parameters
    ----------
    rng : numpy.random.Generator
        The solver's generator.
    candidates : numpy.ndarray
        The population indices donors are drawn for.
    members : int
        The population's size.
    k : int
        Donors per candidate.

    Returns
    -------
    numpy.ndarray
        len(candidates) × k: distinct population indices in [0, ``members``) other than the
        candidate itself, each ordered tuple equally likely (rows with a repeat drawn again).
    """
    out = np.empty((len(candidates), k), dtype=np.intp)
    todo = np.arange(len(candidates))
    while todo.size:
        draw = rng.integers(0, members - 1, size=(todo.size, k))
        draw += draw >= candidates[todo, None]  # skip the candidate itself
        ordered = np.sort(draw, axis=1)
        distinct = np.all(ordered[:, 1:] != ordered[:, :-1], axis=1)
        out[todo[distinct]] = draw[distinct]
        todo = todo[~distinct]
    return out


class DonorsAtOnce(DifferentialEvolutionSolver):
    """scipy's solver; a generation's trial vectors (binomial crossover) made for all members at once."""

    def _mutate_many(self, candidates: np.ndarray) -> np.ndarray:
        if callable(self.strategy) or self.strategy not in self._binomial:
            return super()._mutate_many(candidates)
        rng = self.random_number_generator
        S, p = len(candidates), self.parameter_count
        samples = donors(rng, candidates, self.num_population_members)
        if self.strategy == "currenttobest1bin":
            bprime = self.mutation_func(candidates, samples)
        else:
            bprime = self.mutation_func(samples)
        fill_point = rng.integers(0, p, size=S)  # at least one coefficient from the mutant
        crossovers = rng.uniform(size=(S, p)) < self.cross_over_probability
        crossovers[np.arange(S), fill_point] = True
        return np.where(crossovers, bprime, self.population[candidates])


def differential_evolution(
    cost: Callable[[np.ndarray], np.ndarray], bounds: list[tuple[float, float]], seed: int, **options: object
) -> OptimizeResult:
    """``scipy.optimize.differential_evolution(cost, bounds, rng=default_rng(seed), vectorized=True,
    updating="deferred", **options)``, through :class:`DonorsAtOnce`.

    Parameters
    ----------
    cost : callable
        The cost of a population (p × S parameters -> S costs).
    bounds : list of (float, float)
        Each parameter's range.
    seed : int
        Seed of the generator (the same seed, the same result).
    **options : object
        scipy's other options (popsize, maxiter, tol, polish, ...).

    Returns
    -------
    scipy.optimize.OptimizeResult
        scipy's result: ``x``, ``fun``, ``success``, ...
    """
    with DonorsAtOnce(
        cost, bounds, rng=np.random.default_rng(seed), vectorized=True, updating="deferred", **options
    ) as solver:
        return solver.solve()
