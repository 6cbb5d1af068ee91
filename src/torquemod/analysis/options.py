"""The options of the fit stage (:func:`torquemod.analysis.analyzer.analyze`), all recorded
in fit.json."""

from __future__ import annotations

from dataclasses import dataclass

from torquemod.analysis.creep import ONSET_CRITERIA
from torquemod.errors import OptionError
from torquemod.io.config import check_option_types, coerce_options

__all__ = ["FitOptions"]


@dataclass(frozen=True)
class FitOptions:
    """Options of the fit stage (all recorded in fit.json).

    Attributes
    ----------
    velocity_dependent : bool, default False
        Also fit friction falling with slip velocity (Polach 2005, Eq. 9); needs steps at
        differing speeds.
    lateral : bool, default True
        Model ``CoA = sqrt(f(xi)^2 + (Fy/Fz)^2)`` with the measured lateral force ratio.
    n_starts : int, default 12
        Optimiser start points.
    seed : int, default 0
        Seed of the start points.
    weighted : bool, default True
        Weight the points by the steps' standard errors.
    sigma_floor : float, default 1e-4
        Floor of a point's CoA standard error [-] (the floor applied is
        ``max(sigma_floor, 0.1*median(sigma))``).
    max_rel_stderr : float, default 0.10
        Largest relative standard error of mu for mu to count as determined [-].
    min_saturation_fraction : float, default 0.5
        The largest measured CoA must reach this fraction of mu [-].
    min_peak_fraction : float, default 0.9
        The fitted curve must reach this fraction of mu within ``creepage_limit`` [-].
    creepage_limit : float, default 0.1
        Creepage range over which the curve's peak is sought [-].
    stiffness : float, optional
        Lumped contact stiffness s [-] (Polach 2005, Eq. 3); overrides
        ``rig.contact_stiffness``.
    inertia_kg_m2 : float, optional
        Wheel inertia J [kg m^2]; overrides ``rig.wheel_inertia_kg_m2``.
    theory_constant : float, optional
        Forces the rigid-wheel constant C [-] of ``tan(phi) = C/k``.
    onset_criterion : str, default "tan_ratio"
        ``criterion`` of :func:`torquemod.analysis.creep.saturation_onset`.
    onset_k_sigma, onset_rel_k_drop, onset_tan_ratio : float
        Its ``k_sigma`` [-], ``rel_k_drop`` [-] and ``tan_ratio`` [-].
    onset_min_jump_deg : float, default 5.0
        Its ``min_jump_deg`` [deg].
    onset_baseline_steps : int, default 2
        Its ``baseline_steps``.
    probe : bool, default True
        When the available adhesion from the phase is not determined, also find the probe
        depth (utilisation of one more step) that would determine it; about half of that
        fit's cost. False leaves the depth NaN and changes nothing else of the fit.

    References
    ----------
    .. [1] O. Polach, "Creep forces in simulations of traction vehicles running on adhesion
       limit", Wear 258 (2005) 992-1000.
    """

    velocity_dependent: bool = False
    lateral: bool = True  # model CoA = sqrt(f(xi)^2 + (Fy/Fz)^2) with the measured Fy/Fz
    n_starts: int = 12
    seed: int = 0
    weighted: bool = True
    sigma_floor: float = 1e-4
    max_rel_stderr: float = 0.10
    min_saturation_fraction: float = 0.5
    min_peak_fraction: float = 0.9
    creepage_limit: float = 0.1
    stiffness: float | None = None
    inertia_kg_m2: float | None = None
    theory_constant: float | None = None
    onset_criterion: str = "tan_ratio"
    onset_k_sigma: float = 3.0
    onset_min_jump_deg: float = 5.0
    onset_rel_k_drop: float = 0.5
    onset_tan_ratio: float = 2.0
    onset_baseline_steps: int = 2
    probe: bool = True

    def __post_init__(self) -> None:
        check_option_types(self, "fit")
        if self.n_starts < 1:
            raise OptionError(f"fit option n_starts={self.n_starts}: the Polach fit needs at "
                              "least one start (default 12)")
        if self.onset_criterion not in ONSET_CRITERIA:
            raise OptionError(f"fit option onset_criterion={self.onset_criterion!r}: choose "
                              f"one of {', '.join(ONSET_CRITERIA)}")
        if self.onset_baseline_steps < 1:
            raise OptionError(f"fit option onset_baseline_steps={self.onset_baseline_steps}: "
                              "needs at least 1")
        for name in ("sigma_floor", "max_rel_stderr", "creepage_limit", "onset_tan_ratio"):
            if not getattr(self, name) > 0:
                raise OptionError(f"fit option {name}={getattr(self, name)!r}: must be > 0")
        for name in ("stiffness", "inertia_kg_m2", "theory_constant"):
            value = getattr(self, name)
            if value is not None and not value > 0:
                raise OptionError(f"fit option {name}={value!r}: must be > 0 (or None)")

    @classmethod
    def coerce(cls, options) -> FitOptions:
        return coerce_options(cls, options, "fit")
