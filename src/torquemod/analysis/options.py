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

    ``velocity_dependent`` fits P05 Eq. (9) too (needs differing speeds); ``stiffness``
    overrides ``rig.contact_stiffness``; ``inertia_kg_m2`` overrides ``rig.wheel_inertia_kg_m2``;
    ``theory_constant`` forces C; ``weighted`` uses the steps' standard errors; ``onset_*`` are
    the arguments of :func:`torquemod.analysis.creep.saturation_onset`.
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
