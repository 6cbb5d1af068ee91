"""Polach's creep-force model.

References
----------
O. Polach, "Creep forces in simulations of traction vehicles running on adhesion limit",
Wear 258 (2005) 992-1000 (Eqs. 1-9 there; below "P05").
O. Polach, "A fast wheel-rail forces calculation computer code", Vehicle System Dynamics 33
Suppl. (1999) 728-739 ("P99").

All functions are pure and vectorised over numpy arrays (scalars work too); SI units.
"""

from __future__ import annotations

import math

import numba
import numpy as np


def friction_coefficient(slip_velocity_m_s, *, mu0: float, a_ratio: float, b_s_m: float):
    """Friction coefficient falling with slip velocity: ``mu = mu0*((1-A)*exp(-B*w) + A)``.

    Parameters
    ----------
    slip_velocity_m_s : float or array_like
        Slip velocity w [m/s]; its magnitude is used.
    mu0 : float
        Friction coefficient at zero slip velocity [-].
    a_ratio : float
        A = mu_inf/mu0 [-], the ratio of the friction at infinite slip velocity to mu0.
    b_s_m : float
        B, the exponential decay rate of friction with slip velocity [s/m].

    Returns
    -------
    float or ndarray
        mu [-]. With B = 0 or A = 1 the friction is constant, mu0.

    References
    ----------
    .. [1] O. Polach, "Creep forces in simulations of traction vehicles running on adhesion
       limit", Wear 258 (2005) 992-1000, Eq. (9).

    Examples
    --------
    >>> float(friction_coefficient(0.0, mu0=0.4, a_ratio=0.5, b_s_m=0.6))
    0.4
    >>> round(float(friction_coefficient(1e6, mu0=0.4, a_ratio=0.5, b_s_m=0.6)), 12)
    0.2
    """
    w = np.abs(slip_velocity_m_s)
    return mu0 * ((1.0 - a_ratio) * np.exp(-b_s_m * w) + a_ratio)


def kalker_stiffness(xi_x, xi_y, *, c11: float, c22: float):
    """Kalker coefficient of the combined creepage:
    ``c_jj = sqrt((c11*xi_x/xi)^2 + (c22*xi_y/xi)^2)``, ``xi = sqrt(xi_x^2 + xi_y^2)``.

    Parameters
    ----------
    xi_x, xi_y : float or array_like
        Longitudinal and lateral creepage [-].
    c11, c22 : float
        Kalker's longitudinal and lateral creepage coefficients [-] (Kalker 1990,
        Table E.3; :func:`torquemod.analysis.contact.kalker.kalker_coefficients`).

    Returns
    -------
    ndarray
        c_jj [-]; c11 at zero total creepage.

    References
    ----------
    .. [1] O. Polach, "Creep forces in simulations of traction vehicles running on adhesion
       limit", Wear 258 (2005) 992-1000, Eq. (4).
    .. [2] J.J. Kalker, "Three-dimensional elastic bodies in rolling contact", Kluwer,
       Dordrecht 1990, Table E.3.

    Examples
    --------
    >>> float(kalker_stiffness(0.01, 0.0, c11=4.12, c22=3.67))
    4.12
    >>> float(kalker_stiffness(0.0, 0.0, c11=4.12, c22=3.67))
    4.12
    """
    xi_x = np.asarray(xi_x, dtype=float)
    xi_y = np.asarray(xi_y, dtype=float)
    xi = np.hypot(xi_x, xi_y)
    with np.errstate(invalid="ignore", divide="ignore"):
        cjj = np.hypot(c11 * xi_x / xi, c22 * xi_y / xi)
    return np.where(xi > 0, cjj, c11)


def stress_gradient(xi, *, shear_modulus_pa: float, a_m: float, b_m: float, c_jj,
                    normal_load_n: float, mu):
    """Gradient of the tangential stress in the adhesion area (dimensionless):
    ``eps = (2/3)*C*pi*a^2*b*xi/(Q*mu)`` with ``C = 3/8*G/a*c_jj``, i.e.
    ``eps = pi*G*a*b*c_jj*|xi|/(4*Q*mu)``.

    Parameters
    ----------
    xi : float or array_like
        Total creepage [-]; its magnitude is used.
    shear_modulus_pa : float
        Combined shear modulus G of wheel and rail [Pa].
    a_m, b_m : float
        Contact-ellipse semi-axes in the rolling and lateral directions [m].
    c_jj : float or array_like
        Kalker coefficient of the combined creepage [-] (:func:`kalker_stiffness`).
    normal_load_n : float
        Wheel load Q [N].
    mu : float or array_like
        Friction coefficient [-].

    Returns
    -------
    float or ndarray
        eps [-].

    References
    ----------
    .. [1] O. Polach, "Creep forces in simulations of traction vehicles running on adhesion
       limit", Wear 258 (2005) 992-1000, Eq. (3), with Eq. (5) for C.
    """
    return np.pi * shear_modulus_pa * a_m * b_m * c_jj * np.abs(xi) / (4.0 * normal_load_n * mu)


def force_function(eps, *, k_a: float, k_s: float):
    """Normalised creep force
    ``F/(Q*mu) = (2/pi)*(kA*eps/(1+(kA*eps)^2) + arctan(kS*eps))``.

    Polach's 1999 creep-force function with the 2005 reduction factors kA and kS.

    Parameters
    ----------
    eps : float or array_like
        Gradient of the tangential stress [-] (:func:`stress_gradient`).
    k_a : float
        Reduction factor kA [-] of the stiffness in the adhesion area.
    k_s : float
        Reduction factor kS [-] of the stiffness in the slip area.

    Returns
    -------
    float or ndarray
        F/(Q*mu) [-], odd in eps, tending to 1 as eps grows. With kA = kS = 1 the initial
        slope is that of Kalker's linear theory.

    References
    ----------
    .. [1] O. Polach, "Creep forces in simulations of traction vehicles running on adhesion
       limit", Wear 258 (2005) 992-1000, Eq. (8).
    .. [2] O. Polach, "A fast wheel-rail forces calculation computer code", Vehicle System
       Dynamics 33 Suppl. (1999) 728-739, Eq. (9).

    Examples
    --------
    >>> float(force_function(0.0, k_a=1.0, k_s=0.5))
    0.0
    >>> round(float(force_function(1e9, k_a=1.0, k_s=1.0)), 6)
    1.0
    """
    ke = k_a * eps
    return (2.0 / np.pi) * (ke / (1.0 + ke * ke) + np.arctan(k_s * eps))


def creep_force(xi_x, xi_y, *, normal_load_n: float, speed_m_s: float, a_m: float, b_m: float,
                c11: float, c22: float, shear_modulus_pa: float, mu0: float, a_ratio: float,
                b_s_m: float, k_a: float, k_s: float):
    """Longitudinal and lateral creep forces of Polach's model, without spin.

    ``F = Q*mu*force_function(eps)``, shared between the directions as
    ``F_x = F*xi_x/xi`` and ``F_y = F*xi_y/xi``; mu falls with the slip velocity
    ``w = xi*V``.

    Parameters
    ----------
    xi_x, xi_y : float or array_like
        Longitudinal and lateral creepage [-], signed.
    normal_load_n : float
        Wheel load Q [N].
    speed_m_s : float
        Rolling speed V [m/s].
    a_m, b_m : float
        Contact-ellipse semi-axes, rolling and lateral [m].
    c11, c22 : float
        Kalker's creepage coefficients [-].
    shear_modulus_pa : float
        Combined shear modulus G [Pa].
    mu0, a_ratio, b_s_m : float
        Friction at zero slip [-], A [-] and B [s/m] of :func:`friction_coefficient`.
    k_a, k_s : float
        Reduction factors kA, kS [-] of :func:`force_function`.

    Returns
    -------
    fx, fy : ndarray
        Creep forces [N] with the signs of the creepages; zero at zero creepage.

    References
    ----------
    .. [1] O. Polach, "Creep forces in simulations of traction vehicles running on adhesion
       limit", Wear 258 (2005) 992-1000, Eq. (1)-(9).
    """
    xi_x = np.asarray(xi_x, dtype=float)
    xi_y = np.asarray(xi_y, dtype=float)
    xi = np.hypot(xi_x, xi_y)
    mu = friction_coefficient(xi * speed_m_s, mu0=mu0, a_ratio=a_ratio, b_s_m=b_s_m)
    cjj = kalker_stiffness(xi_x, xi_y, c11=c11, c22=c22)
    eps = stress_gradient(xi, shear_modulus_pa=shear_modulus_pa, a_m=a_m, b_m=b_m, c_jj=cjj,
                          normal_load_n=normal_load_n, mu=mu)
    f = normal_load_n * mu * force_function(eps, k_a=k_a, k_s=k_s)
    with np.errstate(invalid="ignore", divide="ignore"):
        fx = np.where(xi > 0, f * xi_x / xi, 0.0)
        fy = np.where(xi > 0, f * xi_y / xi, 0.0)
    return fx, fy


def adhesion_curve(xi, *, mu: float, k_a: float, k_s: float, stiffness: float):
    """Coefficient of adhesion against creepage, the lumped form used for fitting:
    ``CoA(xi) = sign(xi)*mu*force_function(stiffness*|xi|/mu)``.

    ``stiffness = pi*G*a*b*c11/(4*Q)`` lumps the contact geometry so that
    ``eps = stiffness*|xi|/mu``; the initial slope is ``2*(kA + kS)*stiffness/pi``.
    Constant friction (no velocity dependence).

    Parameters
    ----------
    xi : float or array_like
        Longitudinal creepage [-], signed.
    mu : float
        Friction coefficient [-].
    k_a, k_s : float
        Reduction factors kA, kS [-].
    stiffness : float
        Lumped contact stiffness s [-].

    Returns
    -------
    ndarray
        CoA [-], with the sign of ``xi``.

    References
    ----------
    .. [1] O. Polach, "Creep forces in simulations of traction vehicles running on adhesion
       limit", Wear 258 (2005) 992-1000, Eq. (3) and Eq. (8).

    Examples
    --------
    >>> float(adhesion_curve(0.0, mu=0.3, k_a=1.0, k_s=0.4, stiffness=50.0))
    0.0
    >>> round(float(adhesion_curve(10.0, mu=0.3, k_a=1.0, k_s=1.0, stiffness=5e4)), 4)
    0.3
    """
    xi = np.asarray(xi, dtype=float)
    eps = stiffness * np.abs(xi) / mu
    return np.sign(xi) * mu * force_function(eps, k_a=k_a, k_s=k_s)


def force_function_slope(eps, *, k_a: float, k_s: float):
    """Derivative d/d eps of :func:`force_function` (even in eps):
    ``(2/pi)*(kA*(1-(kA*eps)^2)/(1+(kA*eps)^2)^2 + kS/(1+(kS*eps)^2))``.

    Parameters
    ----------
    eps : float or array_like
        Gradient of the tangential stress [-].
    k_a, k_s : float
        Reduction factors kA, kS [-].

    Returns
    -------
    float or ndarray
        d(F/(Q*mu))/d eps [-].

    References
    ----------
    .. [1] O. Polach, "Creep forces in simulations of traction vehicles running on adhesion
       limit", Wear 258 (2005) 992-1000, Eq. (8), differentiated.

    Examples
    --------
    >>> import math
    >>> math.isclose(force_function_slope(0.0, k_a=1.0, k_s=1.0), 4 / math.pi)
    True
    """
    ke = k_a * eps
    return (2.0 / np.pi) * (k_a * (1.0 - ke * ke) / (1.0 + ke * ke) ** 2
                            + k_s / (1.0 + (k_s * eps) ** 2))


def adhesion_slope(xi, *, mu: float, k_a: float, k_s: float, stiffness: float):
    """Creep coefficient k = dCoA/dxi of :func:`adhesion_curve` (analytic derivative).

    Parameters
    ----------
    xi : float or array_like
        Longitudinal creepage [-]; the slope is even in xi.
    mu, k_a, k_s, stiffness : float
        As for :func:`adhesion_curve` (all [-]).

    Returns
    -------
    ndarray
        k [-]; ``2*(kA + kS)*stiffness/pi`` at xi = 0.

    References
    ----------
    .. [1] O. Polach, "Creep forces in simulations of traction vehicles running on adhesion
       limit", Wear 258 (2005) 992-1000, Eq. (8), differentiated.
    """
    xi = np.asarray(xi, dtype=float)
    eps = stiffness * np.abs(xi) / mu
    return stiffness * force_function_slope(eps, k_a=k_a, k_s=k_s)


# --------------------------------------------------------------------------------------------
# Scalar kernel for compiled integrators (added for the digital twin)
# --------------------------------------------------------------------------------------------

def creep_force_scalar(xi_x: float, xi_y: float, normal_load_n: float, speed_m_s: float,
                       stiffness_x_n: float, stiffness_y_n: float, mu0: float, a_ratio: float,
                       b_s_m: float, k_a: float, k_s: float) -> tuple[float, float]:
    """Scalar (Fx, Fy) of :func:`creep_force`, written for ``numba.njit``.

    Plain Python floats in and out; use :data:`creep_force_kernel` for the compiled version.

    Parameters
    ----------
    xi_x, xi_y : float
        Longitudinal and lateral creepage [-].
    normal_load_n : float
        Normal load Q [N].
    speed_m_s : float
        Rolling speed V [m/s] (slip velocity w = xi*V).
    stiffness_x_n, stiffness_y_n : float
        Lumped contact stiffnesses ``pi*G*a*b*c11/4`` and ``pi*G*a*b*c22/4`` [N].
    mu0 : float
        Friction coefficient at zero slip velocity [-].
    a_ratio : float
        A = mu_inf/mu0 [-].
    b_s_m : float
        B [s/m].
    k_a, k_s : float
        Reduction factors kA, kS [-].

    Returns
    -------
    fx, fy : float
        Creep forces [N]; (0, 0) at zero creepage.

    Notes
    -----
    ``eps = sqrt((stiffness_x*xi_x)^2 + (stiffness_y*xi_y)^2)/(Q*mu)`` (Eqs. 3-5 of [1]_),
    ``F = 2*Q*mu/pi*(kA*eps/(1 + (kA*eps)^2) + arctan(kS*eps))`` (Eq. 8) with
    ``mu = mu0*((1 - A)*exp(-B*w) + A)`` (Eq. 9).

    References
    ----------
    .. [1] O. Polach, "Creep forces in simulations of traction vehicles running on adhesion
       limit", Wear 258 (2005) 992-1000, Eqs. (1)-(9).
    """
    xi = math.sqrt(xi_x * xi_x + xi_y * xi_y)
    if xi <= 0.0 or normal_load_n <= 0.0:
        return 0.0, 0.0
    mu = mu0 * ((1.0 - a_ratio) * math.exp(-b_s_m * xi * abs(speed_m_s)) + a_ratio)
    sx = stiffness_x_n * xi_x
    sy = stiffness_y_n * xi_y
    eps = math.sqrt(sx * sx + sy * sy) / (normal_load_n * mu)
    ke = k_a * eps
    f = normal_load_n * mu * (2.0 / math.pi) * (ke / (1.0 + ke * ke) + math.atan(k_s * eps))
    return f * xi_x / xi, f * xi_y / xi


#: ``numba.njit`` compiled :func:`creep_force_scalar` (callable from other jitted code).
creep_force_kernel = numba.njit(cache=True, fastmath=False)(creep_force_scalar)


# --------------------------------------------------------------------------------------------
# Averages over the creepage swing of the torque modulation
# --------------------------------------------------------------------------------------------

def swing_nodes(n_nodes: int = 32) -> np.ndarray:
    """``cos(theta_k)`` at equally spaced phases ``theta_k = 2*pi*(k + 1/2)/n``.

    The mean of a smooth periodic function over these nodes is its average over one period
    (the trapezoidal rule, exact for trigonometric polynomials of degree < n_nodes).

    Parameters
    ----------
    n_nodes : int
        Nodes n [-]. Default 32.

    Returns
    -------
    ndarray
        The n cosines [-].

    Examples
    --------
    >>> abs(float(swing_nodes(8).mean())) < 1e-15
    True
    """
    return np.cos(2.0 * np.pi * (np.arange(n_nodes) + 0.5) / n_nodes)


def swing_average(curve, xi, swing, *, n_nodes: int = 32):
    """Period average ``<f(xi + a*cos(theta))>`` of a creep curve over a sinusoidal creepage
    swing.

    The result is the mean CoA that a wheel whose creepage swings by ``a`` shows on a
    static curve (the modulation's own bias of the mean creep-curve points).

    Parameters
    ----------
    curve : callable
        Vectorised function of the *signed* creepage [-] returning the signed longitudinal
        CoA [-] (for a magnitude-only curve pass ``lambda x: sign(x)*g(abs(x))``).
    xi : float or array_like
        Mean creepage [-].
    swing : float or array_like
        Swing amplitude a [-]; ``a = 0`` gives ``f(xi)``.
    n_nodes : int, default 32
        Quadrature nodes over the period (:func:`swing_nodes`).

    Returns
    -------
    ndarray
        Mean CoA [-].

    Examples
    --------
    >>> float(swing_average(lambda x: x ** 2, 0.0, 2.0))  # <(2 cos)^2> = 2
    2.0
    """
    c = swing_nodes(n_nodes)
    xi = np.asarray(xi, dtype=float)[..., None]
    a = np.abs(np.asarray(swing, dtype=float))[..., None]
    return np.mean(curve(xi + a * c), axis=-1)


def swing_slope(curve, xi, swing, *, n_nodes: int = 32, slope=None):
    """Describing-function creep coefficient: the first-harmonic gain
    ``(1/(pi*a)) * integral_0^2pi f(xi + a*cos(theta))*cos(theta) dtheta`` of the creep curve
    for a sinusoidal creepage swing.

    This is the creep coefficient that the modulation actually sees (Eq. (1) of the V-Track
    torque-modulation paper then holds with it at large swing). For ``a -> 0`` it tends to
    ``f'(xi)``.

    Parameters
    ----------
    curve : callable
        As for :func:`swing_average`.
    xi : float or array_like
        Mean creepage [-].
    swing : float or array_like
        Swing amplitude a [-].
    n_nodes : int, default 32
        Quadrature nodes over the period.
    slope : callable, optional
        Analytic ``f'`` used below ``a = 1e-9``.

    Returns
    -------
    ndarray
        Creep coefficient [-].

    References
    ----------
    .. [1] "Experimental Validation of the Torque-Modulation-Based Method for Train-Borne
       Coefficient of Friction Measurement" (TU Delft, V-Track rig), Eq. (1).

    Examples
    --------
    >>> round(float(swing_slope(lambda x: 3.0 * x, 0.1, 0.05)), 12)  # a line: its slope
    3.0
    """
    c = swing_nodes(n_nodes)
    xi = np.asarray(xi, dtype=float)
    a = np.abs(np.asarray(swing, dtype=float))
    a_b, xi_b = np.broadcast_arrays(a, xi)
    small = a_b < 1e-9
    a_safe = np.where(small, 1e-9, a_b)
    gain = 2.0 * np.mean(curve(xi_b[..., None] + a_safe[..., None] * c) * c, axis=-1) / a_safe
    if np.any(small) and slope is not None:
        gain = np.where(small, slope(xi_b), gain)
    return gain
