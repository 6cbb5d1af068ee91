"""The available adhesion from the creep-coefficient progression of a stretch of track: the
on-board use of the one estimator, :func:`torquemod.analysis.friction.fit_available_adhesion`.

The on-board windows give the creep coefficient k directly (with its standard error), so the
fit is in k: ``k(CoA) = k0*s(CoA/P; theta)`` over the family of :mod:`torquemod.analysis.creeplaws`
(Polach with constant and falling friction, Burckhardt, saturating laws), P the **available
adhesion** (the maximum of the adhesion-creepage curve). ``mu`` in :class:`CreepFit` and in
track.parquet is that available adhesion; for a constant-friction law whose curve rises to
its friction it is the friction coefficient.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from torquemod.analysis.friction import AdhesionFit, fit_available_adhesion

__all__ = ["CreepFit", "fit_creep_progression"]


@dataclass(frozen=True)
class CreepFit:
    """One fit of the creep-coefficient progression. ``mu`` [-]: the available adhesion
    (best fit); ``mu_low``/``mu_high``: its 95 % interval (``mu_low`` the lower bound and
    ``mu_high`` NaN when the interval is open); ``determined``: closed and narrow enough;
    ``mu0``: the best law's friction coefficient (meaningful only when
    ``adhesion.mu0_identified``); ``k0`` the initial creep coefficient; ``law`` the best
    member; ``adhesion`` the full :class:`torquemod.analysis.friction.AdhesionFit`."""

    mu: float
    mu_low: float
    mu_high: float
    determined: bool
    mu0: float
    k0: float
    chi2: float
    dof: int
    law: str
    adhesion: AdhesionFit

    def creep_coefficient(self, coa) -> np.ndarray:
        """The fitted k at the CoA values [-] (NaN at or beyond the curve's peak)."""
        return self.k0 * self.adhesion.creep_ratio(coa)


def fit_creep_progression(coa, k, k_se, *, coa_now: float | None = None,
                          ratio_bounds: tuple[float, float] = (0.3, 7.0),
                          mu_span: float = 6.0, max_rel_half_width: float = 0.10,
                          power: bool = True, probe: bool = False,
                          speed_m_s: float | None = None) -> CreepFit | None:
    """Fit creep coefficients ``k`` [-] with standard errors ``k_se`` at utilised adhesions
    ``coa`` [-] (module docstring). ``ratio_bounds``: kA/kS of the Polach members;
    ``power``: also the non-Polach laws; ``mu_span``: the largest P tried, as a multiple of
    the largest CoA; ``probe``: also the probe depth that would determine P; ``speed_m_s``
    [m/s]: the rolling speed (bounds the friction's fall with the slip velocity). ``coa_now`` is
    accepted for compatibility (the available adhesion does not depend on the operating
    point). None when fewer than four usable points remain."""
    del coa_now
    fit = fit_available_adhesion(coa, k, k_se, max_rel_half_width=max_rel_half_width,
                                 p_span=mu_span, probe=probe, ratio_bounds=ratio_bounds,
                                 other_laws=power, speed_m_s=speed_m_s)
    if fit is None:
        return None
    high = fit.high if fit.closed else math.nan
    low = fit.low if fit.closed else fit.lower_bound
    return CreepFit(fit.estimate, low, high, fit.determined, fit.mu0, fit.k0, fit.chi2,
                    fit.dof, fit.law, fit)
