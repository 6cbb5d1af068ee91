"""Hertz's elliptical contact: semi-axes from the normal load and the principal curvatures.

Formulas after K.L. Johnson, *Contact Mechanics*, Cambridge 1985, §3.4 (Eqs. 3.64 and
3.67-3.68 there): with the relative curvatures ``A`` (rolling direction) and ``B``
(lateral), ``A + B = (1/R1x + 1/R2x + 1/R1y + 1/R2y)/2``, the contact modulus
``E* = 1/((1-nu1^2)/E1 + (1-nu2^2)/E2)`` and the ellipse eccentricity ``e``
(``e^2 = 1 - (minor/major)^2``):

    B/A = ((a/b)^2 E(e) - K(e)) / (K(e) - E(e))            for a >= b (A <= B)
    a^3 = 3 N (K(e) - E(e)) / (2 pi E* e^2 A)

K, E are complete elliptic integrals of the first and second kind (parameter m = e^2).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from scipy.special import ellipe, ellipk

from torquemod.errors import InputError


@dataclass(frozen=True)
class ContactEllipse:
    """Hertz contact ellipse.

    Attributes
    ----------
    a_m : float
        Semi-axis in the rolling direction [m].
    b_m : float
        Lateral semi-axis [m].
    p0_pa : float
        Maximum contact pressure [Pa].
    """

    a_m: float
    b_m: float
    p0_pa: float

    @property
    def a_over_b(self) -> float:
        return self.a_m / self.b_m


def contact_modulus(youngs_modulus_pa: float, poisson_ratio: float) -> float:
    """Contact modulus of two bodies of the same material, ``E* = E/(2(1-nu^2))``.

    Parameters
    ----------
    youngs_modulus_pa : float
        Young's modulus E [Pa].
    poisson_ratio : float
        Poisson's ratio nu [-].

    Returns
    -------
    float
        E* [Pa].

    References
    ----------
    .. [1] K.L. Johnson, "Contact Mechanics", Cambridge University Press 1985, Eq. (3.64).

    Examples
    --------
    >>> contact_modulus(2.0, 0.0)
    1.0
    """
    return youngs_modulus_pa / (2.0 * (1.0 - poisson_ratio**2))


def _ratio_b_over_a_curv(m: float) -> float:
    """B/A as a function of m = e^2 for a >= b (Johnson Eq. 3.67 divided by 3.68)."""
    k, e = ellipk(m), ellipe(m)
    return ((1.0 / (1.0 - m)) * e - k) / (k - e)


def hertz_ellipse(normal_load_n: float, *, curvature_x_1_m: float, curvature_y_1_m: float,
                  youngs_modulus_pa: float = 210e9, poisson_ratio: float = 0.28
                  ) -> ContactEllipse:
    """Semi-axes and peak pressure of the Hertz contact ellipse.

    Parameters
    ----------
    normal_load_n : float
        Normal load N [N], positive.
    curvature_x_1_m : float
        Sum of the two bodies' principal curvatures in the rolling direction [1/m]
        (e.g. ``1/R_wheel + 0`` for a straight rail).
    curvature_y_1_m : float
        The sum in the lateral direction [1/m] (``1/r_wheel_profile + 1/r_rail_head``).
    youngs_modulus_pa : float, default 210e9
        Young's modulus E of both bodies [Pa].
    poisson_ratio : float, default 0.28
        Poisson's ratio nu of both bodies [-].

    Returns
    -------
    ContactEllipse
        Semi-axes a (rolling) and b (lateral) [m] and maximum pressure p0 [Pa].

    Raises
    ------
    InputError
        A non-positive load or curvature sum.

    Notes
    -----
    A circle results when the two sums are equal: ``a = (3 N R / (4 E*))^(1/3)`` with
    ``1/R`` the curvature sum (the sphere-on-flat case).

    References
    ----------
    .. [1] K.L. Johnson, "Contact Mechanics", Cambridge University Press 1985, §3.4,
       Eqs. (3.64) and (3.67)-(3.68).

    Examples
    --------
    >>> import math
    >>> e = hertz_ellipse(1000.0, curvature_x_1_m=2.0, curvature_y_1_m=2.0,
    ...                   youngs_modulus_pa=2.0, poisson_ratio=0.0)
    >>> math.isclose(e.a_m, (3 * 1000.0 * 0.5 / 4) ** (1 / 3)), math.isclose(e.a_m, e.b_m)
    (True, True)
    """
    if not (normal_load_n > 0 and curvature_x_1_m > 0 and curvature_y_1_m > 0):
        raise InputError("Hertz contact needs a positive normal load and positive curvature "
                         f"sums (got N={normal_load_n}, kx={curvature_x_1_m}, "
                         f"ky={curvature_y_1_m})")
    e_star = contact_modulus(youngs_modulus_pa, poisson_ratio)
    big_a, big_b = 0.5 * curvature_x_1_m, 0.5 * curvature_y_1_m
    swap = big_a > big_b  # then the long axis is lateral: solve with roles exchanged
    small, large = (big_b, big_a) if swap else (big_a, big_b)
    ratio = large / small
    if ratio - 1.0 < 1e-9:
        major = (3.0 * normal_load_n / (8.0 * e_star * small)) ** (1.0 / 3.0)
        minor = major
    else:
        from scipy.optimize import brentq  # here: scipy.optimize costs ~0.4 s to import
        m = brentq(lambda m: _ratio_b_over_a_curv(m) - ratio, 1e-12, 1.0 - 1e-15,
                   xtol=1e-15, rtol=1e-14, maxiter=500)
        k, e = ellipk(m), ellipe(m)
        major = (3.0 * normal_load_n * (k - e) / (2.0 * math.pi * e_star * m * small)) ** (1 / 3)
        minor = major * math.sqrt(1.0 - m)
    a_m, b_m = (minor, major) if swap else (major, minor)
    p0 = 3.0 * normal_load_n / (2.0 * math.pi * a_m * b_m)
    return ContactEllipse(a_m=float(a_m), b_m=float(b_m), p0_pa=float(p0))
