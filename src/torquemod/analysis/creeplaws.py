"""The family of adhesion-creepage curves the friction estimator searches, in one normalised
form, and its lookup tables.

Normal form
-----------
Every curve is written in the reduced creepage ``x = k0*xi/mu0`` (``k0`` the creep
coefficient dCoA/dxi at zero creepage, ``mu0`` the law's friction scale) as
``CoA(xi) = mu0*F(x)`` with ``F'(0) = 1``. The **available adhesion** is the curve's maximum
``P = mu0*F_pk`` (``F_pk`` the first maximum of F, or its supremum when F rises for ever).
On the rising branch the creep coefficient as a function of the utilisation ``u = CoA/P`` is

    k(CoA) = k0*s(CoA/P),   s(u) = F'(x(u)),   s(0) = 1, s(1) = 0,

which is all a progression of (CoA, k) points can see: the estimator fits P and k0 with
``s`` taken from the tables built here.

Members (the ranges and where they come from)
---------------------------------------------
``polach``
    Polach's constant-friction law (Polach 2005, Eq. 8): ``F(x) = h(x/h0; r)``,
    ``h(y; r) = (2/pi)*(r*y/(1 + (r*y)^2) + arctan(y))``, ``h0 = 2*(r + 1)/pi``,
    ``r = kA/kS`` from 0.3 to 7 (Polach's published sets have 2.5 and 3; below 1, kA < kS,
    the curve overshoots its friction and peaks inside, which ``P`` follows; above about 7.5
    ``h`` stops rising monotonically).
``polach_falling``
    Polach's friction falling with the slip velocity (Polach 2005, Eq. 9):
    ``F(x) = phi(y)*h(y/phi(y); r)``, ``y = x/h0``, ``phi = (1 - A)*exp(-beta*y) + A``,
    ``beta = B*V*mu0/K`` (``K = k0/h0``). A from 0.3 to 0.8 (Polach 2005 gives 0.4 for dry
    and wet rail; a falling-friction fit to the Engel-Beck-Alders locomotive curve gives
    0.42); B from 0.1 to 1 s/m (0.2 wet, 0.6 dry in Polach 2005; 0.8 in that fit) over
    speeds of 1-40 m/s and ``mu0/k0`` of 5e-4..0.024 give beta of about 1e-4..5: the grid
    covers 1e-4..4 (even a slight fall makes a curve that would rise for ever peak, far out
    where it rises slowly: at a rig's few km/h beta is 1e-4..0.3). r on a coarser grid over
    the same range as ``polach``.
``burckhardt``
    Burckhardt's law (Burckhardt 1993; Kiencke and Nielsen 2000):
    ``CoA = c1*(1 - exp(-c2*xi)) - c3*xi``, normalised ``F(x) = (1 + d)*(1 - exp(-x)) - d*x``
    with ``d = c3/(c1*c2 - c3)``: 0 (ice) to 0.08 (dry cobblestone) in the published
    road-surface table; the grid spans 0.003..0.3.
``saturation``
    Saturating constant-friction laws ``s(u) = (1 - u^p)^q``: ``p = q = 1`` is the
    exponential approach ``1 - exp(-x)`` (Burckhardt with d = 0), ``p = 2, q = 1`` is
    ``tanh``, ``q = 1/2`` Carter's two-dimensional rolling-contact law, ``q = 2/3`` the
    Vermeulen-Johnson/Shen-Hedrick-Elkins cubic. p from 0.7 to 4, q from 0.5 to 1.5.
    A tail of steeper falls at ``p = 1`` only, ``s = (1 - u)^q`` with q from 1.5 to 2.25:
    q = 2 is the hyperbolic saturation ``F = x/(1 + x)``, whose slope falls as ``(1 - u)^2``
    from the start (as Polach's constant-friction law does near its friction). At p = 1
    these curves and the mixtures of two of them are convex over the whole range, so they
    cannot pass through a straight or concave fall of s (the exponential law, Burckhardt's)
    and then peak higher; members with q >= 2 at p > 1 bend from concave to convex and do
    (with them the exponential law probed to 90 % on a train was determined in 46 % of
    records instead of 94 %).
``knee``
    Linear up to a knee, then saturating: the brush model with uniform pressure (Dugoff,
    Fancher and Segel 1970) keeps the initial slope up to half its friction and then follows
    ``F = 1 - 1/(4x)``; generalised to a knee at ``u = kappa``:
    ``s(u) = 1`` up to kappa, ``((1 - u)/(1 - kappa))^2`` beyond, i.e.
    ``F(x) = 1 - (1 - kappa)^2/(1 - 2*kappa + x)`` for ``x >= kappa``. kappa from 0.3 to 0.7
    (Dugoff's law: 0.5; kappa = 0 is the hyperbolic member above). No rail law of the list
    above keeps its slope that long; the member is there so that curves with a sharp
    transition to saturation widen the interval instead of being fitted by a smooth member
    that peaks just above the points. Knees below 0.3 are left out: with kappa = 0.2
    Burckhardt's law probed to 80 % on board was matched by knee curves peaking 1.4 times
    higher and was no longer determined. The estimator leaves the knee out when asked
    (``knee=False`` in :mod:`torquemod.analysis.friction`).

Nothing here knows how a test curve was made: the estimator's coverage on laws outside this
family is measured by ``benchmarks/friction_coverage.py`` with generators written apart.

Tables
------
:func:`family_tables` gives, for every member, ``s`` and ``ds/du`` on a uniform grid of u
(NaN beyond the peak) and ``F_pk``; with ``swing=True`` also the change of the
describing-function slope under a sinusoidal creepage swing of amplitude ``a`` (reduced
units ``a*k0/mu0``) about the mean point whose swing-averaged CoA is ``u*P``, on a coarser
grid of (u, a) (the first harmonic of F over the swing divided by its amplitude; Gelb and
Vander Velde 1968).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from itertools import pairwise

import numpy as np
from numba import njit

from torquemod._util.arraycache import cached_arrays, source_digest
from torquemod.analysis.polachshape import polach_h

__all__ = ["FAMILY", "N_U", "SWING_A", "FamilyTables", "Member", "family", "family_tables",
           "member_curve", "mixture_curve", "neighbour_pairs"]

#: points of the uniform utilisation grid of the small-signal tables
N_U = 2001
#: points of the utilisation grid of the swing tables
N_U_SWING = 401
#: the swing amplitudes (reduced creepage a*k0/mu0) of the swing tables
SWING_A = np.array([0.0, 0.05, 0.1, 0.17, 0.25, 0.35, 0.5, 0.7, 0.95, 1.25, 1.6, 2.0, 2.6, 3.3,
                    4.2])

R_GRID = np.geomspace(0.3, 7.0, 33)
R_GRID_FALLING = np.geomspace(0.3, 7.0, 9)
A_GRID = (0.3, 0.45, 0.6, 0.8)
BETA_GRID = np.geomspace(1e-4, 4.0, 10)
D_GRID = (0.003, 0.01, 0.03, 0.1, 0.3)
P_GRID = np.geomspace(0.7, 4.0, 9)
Q_GRID = (0.5, 2.0 / 3.0, 0.8, 1.0, 1.25, 1.5)
#: q of the steeper saturating members, at p = 1 only: s = (1 - u)^q
Q_TAIL = (1.5, 1.75, 2.0, 2.25)
KAPPA_GRID = (0.3, 0.4, 0.5, 0.6, 0.7)

#: the member laws' names
FAMILY = ("polach", "polach_falling", "burckhardt", "saturation", "knee")


@dataclass(frozen=True)
class Member:
    """One curve of the family of creep laws.

    Attributes
    ----------
    law : str
        One of :data:`FAMILY`.
    params : tuple of float
        ``polach``: (r,); ``polach_falling``: (r, A, beta); ``burckhardt``: (d,);
        ``saturation``: (p, q); ``knee``: (kappa,); all dimensionless [-].
    """

    law: str
    params: tuple

    @property
    def beyond_rail_laws(self) -> bool:
        """Whether no rail law needs this member: a knee, or the p = 1 tail beyond
        :data:`Q_GRID` (:data:`Q_TAIL`; Dugoff's and the hyperbolic law)."""
        return self.law == "knee" or (self.law == "saturation" and self.params[0] == 1.0
                                      and self.params[1] > Q_GRID[-1])


def family() -> tuple[Member, ...]:
    """Every member of the family, in the order of the tables' rows.

    Returns
    -------
    tuple of Member
        The Polach [1]_ members (constant and falling friction), Burckhardt [2]_, the
        saturating laws and the knee members, on the module's grids.

    References
    ----------
    .. [1] O. Polach, "Creep forces in simulations of traction vehicles running on adhesion
       limit", Wear 258 (2005) 992-1000, Eqs. (8), (9).
    .. [2] M. Burckhardt, "Fahrwerktechnik: Radschlupf-Regelsysteme", Vogel, Würzburg 1993.
    """
    out = [Member("polach", (float(r),)) for r in R_GRID]
    out += [Member("polach_falling", (float(r), a, float(b)))
            for a in A_GRID for b in BETA_GRID for r in R_GRID_FALLING]
    out += [Member("burckhardt", (d,)) for d in D_GRID]
    out += [Member("saturation", (float(p), q)) for q in Q_GRID for p in P_GRID]
    out += [Member("saturation", (1.0, q)) for q in Q_TAIL]
    out += [Member("knee", (k,)) for k in KAPPA_GRID]
    return tuple(out)


@lru_cache(maxsize=1)
def neighbour_pairs() -> np.ndarray:
    """(K, 2) indices of the members that are neighbours on one parameter's grid (r of
    ``polach``; r, A and beta of ``polach_falling``; d of ``burckhardt``; p and q of
    ``saturation``, and q of its p = 1 tail; kappa of ``knee``). The estimator fits every
    non-negative mixture ``(alpha*s_a + beta*s_b)/(alpha + beta)`` of a pair: itself a valid
    curve (s falls from 1 to 0), so the family is continuous along those grids instead of
    stepping with them."""
    members = family()
    index = {(m.law, m.params): i for i, m in enumerate(members)}
    pairs = []

    def link(law, seq):
        for a, b in pairwise(seq):
            pairs.append((index[(law, a)], index[(law, b)]))

    link("polach", [(float(r),) for r in R_GRID])
    for a in A_GRID:
        for b in BETA_GRID:
            link("polach_falling", [(float(r), a, float(b)) for r in R_GRID_FALLING])
        for r in R_GRID_FALLING:
            link("polach_falling", [(float(r), a, float(b)) for b in BETA_GRID])
    for b in BETA_GRID:
        for r in R_GRID_FALLING:
            link("polach_falling", [(float(r), a, float(b)) for a in A_GRID])
    link("burckhardt", [(d,) for d in D_GRID])
    for q in Q_GRID:
        link("saturation", [(float(p), q) for p in P_GRID])
    for p in P_GRID:
        link("saturation", [(float(p), q) for q in Q_GRID])
    link("saturation", [(1.0, q) for q in Q_TAIL])
    link("knee", [(k,) for k in KAPPA_GRID])
    return np.array(pairs, dtype=np.int64)


def _saturation_curve(p: float, q: float, x_max: float) -> tuple[np.ndarray, np.ndarray]:
    """(x, F) of the saturating law ``dF/dx = (1 - F^p)^q``: ``x(u) = int_0^u du/s``
    (trapezoid on a grid that crowds towards u = 1, where 1/s diverges), then F = 1 beyond
    (full sliding: the law's friction)."""
    u = np.concatenate([np.linspace(0.0, 0.9, 3001)[:-1], 1.0 - np.geomspace(0.1, 1e-12, 4000)])
    inv = 1.0 / (1.0 - u ** p) ** q
    x = np.concatenate([[0.0], np.cumsum(0.5 * (inv[1:] + inv[:-1]) * np.diff(u))])
    keep = x < x_max
    x, u = x[keep], u[keep]
    tail = np.linspace(x[-1], x_max, 200)[1:]
    return np.concatenate([x, tail]), np.concatenate([u, np.full(tail.size, u[-1])])


def member_curve(m: Member, x: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """A member's curve in the normal form ``CoA = mu0*F(x)``, ``F'(0) = 1``.

    Parameters
    ----------
    m : Member
        The member.
    x : ndarray or None
        Reduced creepage x = k0*xi/mu0 [-]; None: a grid from 0 well past the peak (the
        given ``x`` is used only by the closed-form laws; the saturating laws use their own
        grid up to its last value).

    Returns
    -------
    x : ndarray
        Reduced creepage [-].
    f : ndarray
        F(x) [-].

    Examples
    --------
    >>> x, f = member_curve(Member("burckhardt", (0.0,)), np.array([0.0, 1.0]))
    >>> [round(float(v), 6) for v in f]
    [0.0, 0.632121]
    """
    if x is None:
        x = np.concatenate([[0.0], np.geomspace(1e-5, 2e3, 6000)])
    if m.law == "polach":
        r = m.params[0]
        h0 = 2.0 * (r + 1.0) / np.pi
        return x, polach_h(x / h0, r)
    if m.law == "polach_falling":
        r, a, beta = m.params
        h0 = 2.0 * (r + 1.0) / np.pi
        y = x / h0
        phi = (1.0 - a) * np.exp(-beta * y) + a
        return x, phi * polach_h(y / phi, r)
    if m.law == "burckhardt":
        d = m.params[0]
        return x, (1.0 + d) * (1.0 - np.exp(-x)) - d * x
    if m.law == "knee":
        kappa = m.params[0]
        tail = 1.0 - (1.0 - kappa) ** 2 / (1.0 - 2.0 * kappa + np.maximum(x, kappa))
        return x, np.where(x <= kappa, x, tail)
    return _saturation_curve(m.params[0], m.params[1], float(x[-1]))


def _rising(x: np.ndarray, f: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """(x, F) up to the first maximum, and F_pk."""
    stop = np.flatnonzero(np.diff(f) <= 0)
    n = stop[0] + 1 if stop.size else f.size
    return x[:n], f[:n], float(f[n - 1])


@dataclass(frozen=True)
class FamilyTables:
    """The lookup tables of :func:`family_tables`.

    S members, utilisation ``u = linspace(0, 1, N_U)``.

    Attributes
    ----------
    members : tuple of Member
        The members, one per row.
    f_peak : ndarray
        (S,) F_pk = P/mu0 [-].
    s : ndarray
        (S, N_U) s(u) = k/k0 [-], NaN at and beyond the peak.
    ds : ndarray
        (S, N_U) ds/du [-].
    swing : ndarray or None
        (S, N_U_SWING, len(SWING_A)) change of the describing-function slope from s at the
        same mean utilisation under a creepage swing [-] (NaN where the swing-averaged curve
        does not reach that utilisation); None without swing tables.
    beta_h : ndarray
        (S,) beta/h0 of the falling-friction members [-] (the friction falls as
        ``exp(-beta_h*x)`` in the reduced creepage x), 0 for the others.
    falling : ndarray of bool
        (S,) the member's friction falls with the slip velocity.
    s_t, ds_t : ndarray or None
        (N_U, S) ``s`` and ``ds`` utilisation-major (C-contiguous; ``s`` and ``ds`` are their
        transposed views when the tables come from :func:`family_tables`): one utilisation
        of every member lies together in memory, which is how the chi2 grid reads them.
    swing_t : ndarray or None
        (N_U_SWING, S, len(SWING_A)) ``swing`` utilisation-major in the same way.
    """

    members: tuple[Member, ...]
    f_peak: np.ndarray
    s: np.ndarray
    ds: np.ndarray
    swing: np.ndarray | None
    beta_h: np.ndarray
    falling: np.ndarray
    s_t: np.ndarray | None = None
    ds_t: np.ndarray | None = None
    swing_t: np.ndarray | None = None


def _small_signal(m: Member) -> tuple[np.ndarray, np.ndarray, float, np.ndarray, np.ndarray]:
    x, f = member_curve(m)
    xr, fr, fpk = _rising(x, f)
    slope = np.gradient(fr, xr)
    slope[0] = 1.0
    u = fr / fpk
    ug = np.linspace(0.0, 1.0, N_U)
    s = np.interp(ug, u, np.maximum(slope, 0.0), right=np.nan)
    s[-1] = np.nan
    ds = np.gradient(s, ug)
    return x, f, fpk, s, ds


@njit(cache=True, nogil=True)
def _swing_moments(x: np.ndarray, f: np.ndarray, x0: np.ndarray, a: np.ndarray,
                   c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean and first-harmonic slope of the odd curve (x, F) over ``x0 + a*cos(theta)`` at
    the nodes whose cosines are ``c`` (midpoint rule over one period), (len(x0), len(a))."""
    n0, na, nc = x0.size, a.size, c.size
    mean = np.zeros((n0, na))
    slope = np.zeros((n0, na))
    for i in range(n0):
        for j in range(na):
            sm = 0.0
            sh = 0.0
            for t in range(nc):
                z = x0[i] + a[j] * c[t]
                az = abs(z)
                k = min(max(np.searchsorted(x, az) - 1, 0), x.size - 2)
                w = min(max((az - x[k]) / (x[k + 1] - x[k]), 0.0), 1.0)
                fz = f[k] * (1.0 - w) + f[k + 1] * w
                if z < 0.0:
                    fz = -fz
                sm += fz
                sh += fz * c[t]
            mean[i, j] = sm / nc
            slope[i, j] = 2.0 * sh / (nc * a[j]) if a[j] > 0.0 else np.nan
    return mean, slope


def _swing_rows(x: np.ndarray, f: np.ndarray, fpk: float, s_u: np.ndarray) -> np.ndarray:
    """(N_U_SWING, len(SWING_A)): describing-function slope minus s at the same mean
    utilisation, by a 16-node midpoint rule over the swing's phase."""
    c = np.cos((np.arange(16) + 0.5) * (2.0 * np.pi / 16))
    xr, fr, _ = _rising(x, f)
    levels = np.linspace(0.0, fr[-1], 400)[:-1]
    x0 = np.concatenate([np.interp(levels, fr, xr), xr[-1] * np.linspace(1.0, 1.6, 40)])
    ug = np.linspace(0.0, 1.0, N_U_SWING)
    s_small = np.interp(ug, np.linspace(0.0, 1.0, N_U), s_u)
    out = np.full((N_U_SWING, SWING_A.size), np.nan)
    out[:, 0] = 0.0
    mean, slope = _swing_moments(x, f, x0, SWING_A[1:], c)
    for j in range(1, SWING_A.size):
        m = mean[:, j - 1] / fpk
        _, mr, _ = _rising(x0, m)
        n = mr.size
        out[:, j] = np.interp(ug, m[:n], slope[:n, j - 1], right=np.nan) - s_small
    return out


@lru_cache(maxsize=2)
def family_tables(swing: bool = False) -> FamilyTables:
    """The tables of every member of :func:`family` (module docstring); built once per
    machine (about a second; the swing tables a few more) and kept in torquemod's disk
    cache (:func:`torquemod._util.arraycache.cached_arrays`, keyed by the versions, the
    grids and this module's source), then loaded in each process."""
    members = family()
    key = {"swing": bool(swing), "n_u": N_U, "n_u_swing": N_U_SWING,
           "swing_a": SWING_A.tolist(), "members": [[m.law, list(m.params)] for m in members],
           "source": _source_digest()}
    names = ("f_peak", "s_t", "ds_t", "beta_h", "falling") + (("swing_t",) if swing else ())
    # one name per table set: a new file of one set removes only that set's older files
    name = "creeplaw_family_swing" if swing else "creeplaw_family"
    # stored utilisation-major (the chi2 grid's order), the member-major tables are views
    arr = cached_arrays(name, key, lambda: _utilisation_major(_build_tables(members, swing)),
                        names=names)
    sw_t = arr.get("swing_t")
    return FamilyTables(members, arr["f_peak"], arr["s_t"].T, arr["ds_t"].T,
                        None if sw_t is None else sw_t.transpose(1, 0, 2), arr["beta_h"],
                        arr["falling"], s_t=arr["s_t"], ds_t=arr["ds_t"], swing_t=sw_t)


def _utilisation_major(tables: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The tables ``s``, ``ds`` and ``swing`` of :func:`_build_tables` as C-contiguous
    utilisation-major copies ``s_t``, ``ds_t``, ``swing_t`` (the same values)."""
    out = {k: v for k, v in tables.items() if k not in ("s", "ds", "swing")}
    out["s_t"] = np.ascontiguousarray(tables["s"].T)
    out["ds_t"] = np.ascontiguousarray(tables["ds"].T)
    if "swing" in tables:
        out["swing_t"] = np.ascontiguousarray(tables["swing"].transpose(1, 0, 2))
    return out


def _source_digest() -> str:
    """Digest of the code that builds the tables: this module, the Polach shape and the
    Polach force law it uses."""
    import torquemod.analysis.contact.polach as contact_polach
    import torquemod.analysis.polachshape as polachshape
    return source_digest(__file__, polachshape.__file__, contact_polach.__file__)


def _build_tables(members: tuple[Member, ...], swing: bool) -> dict[str, np.ndarray]:
    """The arrays of :class:`FamilyTables` for ``members``, computed."""
    rows = [_small_signal(m) for m in members]
    out = {"f_peak": np.array([r[2] for r in rows]), "s": np.array([r[3] for r in rows]),
           "ds": np.array([r[4] for r in rows]),
           "beta_h": np.array([m.params[2] * np.pi / (2.0 * (m.params[0] + 1.0))
                               if m.law == "polach_falling" else 0.0 for m in members]),
           "falling": np.array([m.law == "polach_falling" for m in members])}
    if swing:
        out["swing"] = np.array([_swing_rows(r[0], r[1], r[2], r[3]) for r in rows])
    return out


def mixture_curve(law: str, params) -> np.ndarray | None:
    """The normalised creep-coefficient curve ``s(u)`` of a member or of a neighbour mixture.

    A member of the family with ``law`` and ``params``, or the mixture
    ``(1 - f)*s_a + f*s_b`` of two neighbouring members (:func:`neighbour_pairs`) whose
    parameters mix with the same ``f`` to ``params`` (the one parameter the pair differs in
    gives ``f``): the curves the friction estimator fits. Only the members it needs are
    tabulated (milliseconds, not the whole family's second).

    Parameters
    ----------
    law : str
        One of :data:`FAMILY`.
    params : sequence of float
        The law's parameters (dimensionless, as in :class:`Member`).

    Returns
    -------
    numpy.ndarray or None
        ``s`` on the uniform utilisation grid of :data:`N_U` points from 0 to 1 (NaN at the
        peak, as in :func:`family_tables`); None when ``params`` are neither a member's nor
        a neighbour mixture's.
    """
    p = np.asarray(params, dtype=float)
    members = family()
    same = [i for i, m in enumerate(members)
            if m.law == law and np.array_equal(np.asarray(m.params, float), p)]
    if same:
        return _small_signal(members[same[0]])[3]
    for ia, ib in neighbour_pairs():
        ma, mb = members[ia], members[ib]
        if ma.law != law or len(ma.params) != p.size:
            continue
        pa, pb = np.asarray(ma.params, float), np.asarray(mb.params, float)
        varies = pa != pb
        if varies.sum() != 1 or np.any(p[~varies] != pa[~varies]):
            continue
        k = int(np.flatnonzero(varies)[0])
        f = (p[k] - pa[k]) / (pb[k] - pa[k])
        if 0.0 < f < 1.0:
            return (1.0 - f) * _small_signal(ma)[3] + f * _small_signal(mb)[3]
    return None
