"""Named Polach parameter sets, each with its source (pvlib-style parameter table).

``POLACH_PRESETS[name]`` is a :class:`PolachParameters`; ``source`` says where the numbers
come from or that they are assumed.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

from torquemod.errors import InputError


@dataclass(frozen=True)
class PolachParameters:
    """Polach (2005) friction and reduction parameters: ``mu0`` [-], ``a_ratio`` A =
    mu_inf/mu0 [-], ``b_s_m`` B [s/m] (Eq. 9), ``k_a``, ``k_s`` [-] (Eq. 8), and ``source``."""

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
    """Look up a preset by name; unknown names raise InputError listing the known ones."""
    try:
        return POLACH_PRESETS[name]
    except KeyError:
        raise InputError(f"unknown Polach preset '{name}'",
                         hint=f"use one of {', '.join(sorted(POLACH_PRESETS))}") from None
