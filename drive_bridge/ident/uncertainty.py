"""The std an identification reports of its model's parameters: the model's own, as its fit set it,
widened apart from the model where evidence beside the fit shows it larger -- two runs that
disagree, friction that depends on the speed, a jackknife above the HAC std but short of the factor
that widens it inside the fit.  The model itself is never changed after ``fit`` (scikit-learn's
rule: fitted attributes are the fit's alone)."""

from __future__ import annotations

import numpy as np

from .model import BASE, AxisModel, std_from_cov


class Uncertainty:
    """The covariance of a fitted model's coefficients as an identification reports it.

    Parameters
    ----------
    model : AxisModel
        The fitted model; its ``cov_`` is copied, never changed.
    """

    def __init__(self, model: AxisModel):
        self.model = model
        #: the coefficients' covariance as reported (``coef_names`` order) [SI²]
        self.cov = model.cov_.copy()

    def widen(self, param: str, gap: float) -> None:
        """Widen the std of J, c0 or c1, in quadrature, by half ``gap``.

        Parameters
        ----------
        param : {"J", "c0", "c1"}
            The parameter.
        gap : float
            The difference the std must cover twice [its unit].
        """
        i = BASE.index(param)
        self.cov[i, i] += (gap / 2) ** 2

    @property
    def coef_std(self) -> np.ndarray:
        """The std of each coefficient (``coef_names`` order), as reported [SI]."""
        return std_from_cov(self.cov)

    @property
    def param_std(self) -> dict[str, float]:
        """The std of J, c0, c1 and every effect's parameters (``<effect>.<name>``), as reported [SI]."""
        return self.model.std_of(self.cov)
