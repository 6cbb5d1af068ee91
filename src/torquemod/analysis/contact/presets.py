"""Named Polach parameter sets, each with its source (pvlib-style parameter table).

``POLACH_PRESETS[name]`` is a :class:`PolachParameters`; ``source`` says where the numbers
come from or that they are assumed.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

from torquemod.errors import InputError


@dataclass(frozen=True)
class PolachParameters:
    """Polach's friction and reduction parameters of one rail condition.

    Attributes
    ----------
    mu0 : float
        Friction coefficient at zero slip velocity [-].
    a_ratio : float
        A = mu_inf/mu0 [-] (Eq. 9 of [1]_).
    b_s_m : float
        B, the exponential decay rate of friction with slip velocity [s/m] (Eq. 9).
    k_a : float
        Reduction factor in the area of adhesion kA [-] (Eq. 8).
    k_s : float
        Reduction factor in the area of slip kS [-] (Eq. 8).
    source : str
        Where the values come from.

    References
    ----------
    .. [1] O. Polach, "Creep forces in simulations of traction vehicles running on adhesion
       limit", Wear 258 (2005) 992-1000.
    """

    mu0: float
    a_ratio: float
    b_s_m: float
    k_a: float
    k_s: float
    source: str

    def as_dict(self) -> dict:
        """The numeric parameters as keyword arguments (without ``source``)."""
        d = asdict(self)
        d.pop("source")
        return d


POLACH_PRESETS: dict[str, PolachParameters] = {
    "dry": PolachParameters(
        mu0=0.55, a_ratio=0.40, b_s_m=0.60, k_a=1.00, k_s=0.40,
        source="Polach, Wear 258 (2005) 992-1000, dry rail; values inferred from a simulator "
               "(not checked against the paper's Table 1)"),
    "wet": PolachParameters(
        mu0=0.30, a_ratio=0.40, b_s_m=0.20, k_a=0.30, k_s=0.10,
        source="Polach, Wear 258 (2005) 992-1000, wet rail; values inferred from a simulator "
               "(not checked against the paper's Table 1)"),
    "vtrack": PolachParameters(
        mu0=0.255, a_ratio=0.80, b_s_m=2.0, k_a=0.20, k_s=0.20,
        source="assumed for the V-Track twin: tuned so that the creep curve peaks at "
               "R*Fx = 69.5 N*m, CoA 0.245 (the paper's sixth step, 65.82 N*m, at 95 % of it) "
               "and a noise-free Polach fit without velocity dependence of the six "
               "steady-state points gives mu within 0.01 of the paper's 0.24 "
               "(tests/twins/test_theory.py)"),
}


def polach_preset(name: str) -> PolachParameters:
    """A preset of Polach parameters by name.

    Parameters
    ----------
    name : str
        One of :data:`POLACH_PRESETS` (vtrack, dry, wet).

    Returns
    -------
    PolachParameters
        The preset.

    Raises
    ------
    InputError
        An unknown name, listing the known ones.
    """
    try:
        return POLACH_PRESETS[name]
    except KeyError:
        raise InputError(f"unknown Polach preset '{name}'",
                         hint=f"use one of {', '.join(sorted(POLACH_PRESETS))}") from None
