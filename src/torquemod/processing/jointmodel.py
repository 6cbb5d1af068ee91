"""The joint least-squares speed model of one cycle (ours): the modulation, the slow speed
variation, the rotation orders and the modulation's harmonics fitted together
(:class:`SpeedModel`, :func:`fit_speed_model`), the modulation's columns and its harmonics.
Used by the per-cycle steps of :mod:`torquemod.processing.chain` through
:mod:`torquemod.processing.speedmodel`.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numba
import numpy as np
from scipy.signal import get_window

from torquemod.dsp import filters, jointfit, lstsq, numpyblas, projection

#: the half-width [Hz] of the bins near the modulation whose noise the residual keeps
#: (:meth:`SpeedModel.noise_depletion`; the bins :func:`~torquemod.dsp.phase.local_noise_psd`
#: reads)
NOISE_HALF_WIDTH_HZ = 0.75


@numba.njit(cache=True, nogil=True)
def hypot(x: float, y: float) -> float:
    """``sqrt(x*x + y*y)`` [their unit] by the C library's ``hypot``, the function behind
    ``np.hypot`` on float64 (the same numbers; Python's ``math.hypot`` rounds its own way),
    at a compiled call's cost instead of a ufunc's on two scalars (~0.2 against ~1.5 us)."""
    return math.hypot(x, y)


@functools.lru_cache(maxsize=16)
def _hann(n: int) -> np.ndarray:
    """``get_window("hann", n)`` (periodic), cached read-only: one per record length."""
    w = get_window("hann", n)
    w.setflags(write=False)
    return w


@functools.lru_cache(maxsize=16)
def _hann_fourier(n: int, bins: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray]:
    """The Hann-windowed Fourier vectors ``w[t]*exp(-2j*pi*t*k/n)`` of the DFT bins ``k`` of an
    ``n``-sample record and their squared norms, cached read-only (the bins near the
    modulation are the same for most cycles of a given length). Real columns: the real
    parts of all bins, then their imaginary parts (real products with the design)."""
    v = _hann(n)[:, None] * np.exp(-2j * np.pi * np.outer(np.arange(n), np.array(bins)) / n)
    power = np.sum(np.abs(v) ** 2, axis=0)
    v = np.hstack([v.real, v.imag])
    v.setflags(write=False)
    power.setflags(write=False)
    return v, power


@dataclass(frozen=True)
class SpeedModel:
    """The joint least-squares model of one cycle's speeds and torque.

    For every channel ``x = modulation + slow + orders + harmonics + residual`` with the
    modulation ``c*cos + s*sin`` at ``modulation_hz``, the slow part in
    :func:`~torquemod.dsp.basis.slow_basis`, the rotation orders in
    :func:`~torquemod.dsp.basis.order_design` and the modulation's own harmonics (the creep
    curve's bend distorts the wheel's answer; :func:`modulation_harmonics`). One design
    serves every channel, so any linear functional of it (the step-8 mean) treats a speed
    variation that wheel and platform share alike, and it cancels in the creepage of Eq. (3)
    of the V-Track paper.

    Attributes
    ----------
    modulation_hz : float
        Modulation frequency [Hz].
    fs_hz : float
        Sample rate [Hz].
    design : ndarray
        (n, m) design matrix: modulation columns, slow basis, orders, harmonics.
    n_slow : int
        Columns of the slow basis.
    coef : ndarray
        (m, channels) fitted coefficients, in each channel's unit.
    names : tuple of str
        The channels, in the order of ``coef``'s columns.
    factor : LstsqFactor or None
        The design's factorisation, for further solves.
    n_harmonic_columns : int
        Columns of the modulation's harmonics (the last ones). Default 0.
    """

    modulation_hz: float
    fs_hz: float
    design: np.ndarray  # (n, 2 + n_slow + n_orders + n_harmonics)
    n_slow: int
    coef: np.ndarray  # (columns, channels)
    names: tuple[str, ...]
    #: the design's least-squares factor (None when lstsq fell back to the SVD)
    factor: filters.LstsqFactor | None = field(default=None, repr=False, compare=False)
    #: columns of the modulation's harmonics, the design's last ones
    n_harmonic_columns: int = 0
    _parts: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    def part(self, name: str, which: str) -> np.ndarray:
        """``"modulation"``, ``"slow"``, ``"orders"`` or ``"harmonics"`` part of channel
        ``name`` (computed once, read-only)."""
        key = (name, which)
        if key not in self._parts:
            j = self.names.index(name)
            end = self.design.shape[1] - self.n_harmonic_columns
            sl = {"modulation": slice(0, 2), "slow": slice(2, 2 + self.n_slow),
                  "orders": slice(2 + self.n_slow, end), "harmonics": slice(end, None)}[which]
            y = self.design[:, sl] @ self.coef[sl, j]
            y.setflags(write=False)
            self._parts[key] = y
        return self._parts[key]

    def amplitude(self, name: str) -> float:
        """Amplitude of the fitted modulation of channel ``name`` [its unit]."""
        c, s = self.coef[:2, self.names.index(name)].tolist()  # (the same float64s)
        return hypot(c, s)  # (np.hypot's number)

    def variance_factor(self) -> float:
        """Variance of the modulation's coefficients in this joint model over their variance
        with the modulation fitted alone (>= 1): the price in phase noise of separating the
        modulation from the slow part and the orders, at the Cramér-Rao bound of the joint
        model (white noise)."""
        d = self.design
        ratio = self._parts.get("variance_ratio", float("nan"))
        if ratio == ratio:  # computed by the fit's compiled call with the numbers of the
            return float(max(1.0, ratio))  # steps below (NaN: not, or it failed)
        m = d[:, :2]
        # (D'D)^-1 restricted to the modulation is (M'(I - P_B)M)^-1, P_B the projection on
        # the other columns (the Schur complement), by a refined least-squares fit on them.
        # Not the block of the inverse of the fit's normal matrix: that squares the design's
        # condition number (~1e6 here) and came out 6e-5 relative off the SVD's (this route:
        # 1e-11, measured). The fit's normal matrix gives the other columns' factor.
        other = d[:, 2:]
        sub = self.factor.trailing(2) if self.factor is not None else None
        if other.shape[1]:
            c_o = sub.solve(m) if sub is not None else filters.lstsq(other, m)[0]
            m_res = m - other @ c_o
        else:
            m_res = m
        return float(max(1.0, _trace_of_inverse_2x2(m_res.T @ m_res)
                         / _trace_of_inverse_2x2(m.T @ m)))

    def noise_depletion(self, *, half_width_hz: float = NOISE_HALF_WIDTH_HZ,
                        basis_t: np.ndarray | None = None) -> float:
        """Fraction (<= 1) of white noise's power near the modulation that the model's
        residual keeps, averaged over the bins :func:`~torquemod.dsp.phase.local_noise_psd`
        reads: ``1 - |Q^H v_f|^2/|v_f|^2`` for the Hann-windowed Fourier vector ``v_f`` of each
        bin and Q an orthonormal basis of the design. The slow basis overlaps the modulation's
        neighbourhood, so its residual understates the noise density there; dividing by this
        restores it (E[r r^T] = sigma^2 (I - H) for least squares).

        ``basis_t``, ``Q_B'`` (``p x n``) of an orthonormal basis of the design's slow and
        order columns (the chain's step-1 search has one), spares the basis of the whole
        design (:func:`~torquemod.dsp.projection.powers_in_span`: the same span, another
        rounding, ~1e-12 relative here; :func:`fit_speed_model` given the same ``basis_t``
        made it already)."""
        made = self._parts.get("noise_kept")
        if made is not None and made[0] is basis_t and half_width_hz == NOISE_HALF_WIDTH_HZ:
            return made[1]
        d = self.design
        n = d.shape[0]
        sel = _bins_near(n, self.fs_hz, self.modulation_hz, half_width_hz)
        if len(sel) < 2:
            return 1.0
        v, v_power = _hann_fourier(n, sel)
        if basis_t is not None and basis_t.shape == (d.shape[1] - 2 - self.n_harmonic_columns,
                                                     n):
            end = d.shape[1] - self.n_harmonic_columns
            qv = projection.powers_in_span(basis_t, np.hstack([d[:, :2], d[:, end:]]), v)
            if qv is not None:
                kept = 1.0 - qv.reshape(2, -1).sum(axis=0) / v_power
                return min(max(float(kept.sum()) / kept.size, 0.05), 1.0)
        fac = self.factor if self.factor is not None else filters.LstsqFactor.of(d)
        qt = projection.orthonormal_basis_t(fac, compiled=True) if fac is not None else None
        if qt is None:
            # a design rank deficient to rounding (the fit fell back to the SVD): Q from
            # the SVD, over its numerical rank
            u, sv, _ = np.linalg.svd(d / np.sqrt(np.einsum("ij,ij->j", d, d)),
                                     full_matrices=False)
            qt = u[:, sv > sv[0] * 1e-10].T
        # Q orthonormal to rounding (CholeskyQR2 from the fit's own factor, the compiled
        # route of dsp.projection; the fraction depends on Q's span alone, so on the route
        # by ~1e-12 relative): the fraction agrees with an SVD of the design to ~1e-12
        # relative and moves by about as little when the inputs move by rounding
        # (tests/processing/test_chain_floor.py). Q = D L^-T from the normal equations alone
        # (the condition number, ~1e6 here, squared) was off by 2-6e-5 relative and moved
        # by as much with any rounding-level change of the design.
        qv = qt @ v  # v: the real parts, then the imaginary parts
        kept = 1.0 - (qv * qv).sum(axis=0).reshape(2, -1).sum(axis=0) / v_power
        # np.clip(np.mean(kept), 0.05, 1.0)'s numbers (NaN stays NaN) on Python floats
        return min(max(float(kept.sum()) / kept.size, 0.05), 1.0)

    def mean(self, name: str) -> float:
        """Step-8 mean: the record's mean less the fitted modulation and rotation orders (the
        mean of the slow part; the residual has zero mean since the constant is fitted)."""
        key = (name, "mean")
        if key not in self._parts:
            slow = self.part(name, "slow")
            self._parts[key] = float(slow.sum()) / slow.size  # np.mean's numbers, cheaper
        return self._parts[key]


def _bins_near(n: int, fs_hz: float, f_hz: float, half_width_hz: float) -> tuple[int, ...]:
    """The DFT bins k (of ``n // 2 + 1``) with ``1.5*df < |k*df - f_hz| <= half_width_hz``,
    ``df = fs_hz/n`` [Hz]: the same float operations as on numpy's arrays, over the
    candidates near ``f_hz`` only."""
    df = fs_hz / n
    lo = max(0, int((f_hz - half_width_hz) / df) - 2)
    hi = min(n // 2, int((f_hz + half_width_hz) / df) + 2)
    near = []
    for k in range(lo, hi + 1):
        if 1.5 * df < abs(k * df - f_hz) <= half_width_hz:
            near.append(k)
    return tuple(near)


def _trace_of_inverse_2x2(a: np.ndarray) -> float:
    """``trace(inv(a))`` of a 2x2 matrix: ``(a00 + a11)/det(a)``."""
    a00, a01, a10, a11 = (float(v) for v in a.ravel())
    return (a00 + a11) / (a00 * a11 - a01 * a10)


@functools.lru_cache(maxsize=16)
def _centred_time(n: int, fs_hz: float) -> np.ndarray:
    """``(arange(n) - (n - 1)/2)/fs_hz`` [s], cached read-only (one per record length)."""
    t = (np.arange(n) - (n - 1) / 2) / fs_hz
    t.setflags(write=False)
    return t


def modulation_columns(n: int, fs_hz: float, modulation_hz: float,
                       harmonics: tuple[int, ...] = ()) -> np.ndarray:
    """``cos`` and ``sin`` of ``2*pi*k*f*t`` for k = 1 and each of the harmonics.

    t is taken from the record's middle, so a fitted phase is decoupled from a small error of
    the frequency.

    Parameters
    ----------
    n : int
        Samples [-].
    fs_hz : float
        Sample rate [Hz].
    modulation_hz : float
        Modulation frequency f [Hz].
    harmonics : tuple of int
        Further harmonics k, in order. Default ().

    Returns
    -------
    ndarray
        (n, 2*(1 + len(harmonics))) columns [-]: the numbers of
        :func:`modulation_columns_reference` from one compiled call
        (:func:`torquemod.dsp.jointfit.tone_columns`).
    """
    return jointfit.tone_columns(int(n), float(fs_hz), float(modulation_hz),
                                 _tone_orders(tuple(int(k) for k in harmonics)))


@functools.lru_cache(maxsize=16)
def _tone_orders(harmonics: tuple[int, ...]) -> np.ndarray:
    """The modulation's orders ``(1, *harmonics)`` as a read-only int64 array (cached)."""
    out = np.array((1, *harmonics), dtype=np.int64)
    out.setflags(write=False)
    return out


def modulation_columns_reference(n: int, fs_hz: float, modulation_hz: float,
                                 harmonics: tuple[int, ...] = ()) -> np.ndarray:
    """:func:`modulation_columns` by numpy, column by column: the reference of the
    compiled route.

    Parameters
    ----------
    n : int
        Samples [-].
    fs_hz : float
        Sample rate [Hz].
    modulation_hz : float
        Modulation frequency f [Hz].
    harmonics : tuple of int
        Further harmonics k, in order. Default ().

    Returns
    -------
    ndarray
        (n, 2*(1 + len(harmonics))) columns ``np.cos(k * w * t)``, ``np.sin(k * w * t)``
        with ``w = 2 pi f`` [-].
    """
    t = _centred_time(int(n), float(fs_hz))
    w = 2 * np.pi * modulation_hz
    out = np.empty((n, 2 + 2 * len(harmonics)))
    for i, k in enumerate((1, *harmonics)):
        out[:, 2 * i] = np.cos(k * w * t)
        out[:, 2 * i + 1] = np.sin(k * w * t)
    return out


@functools.lru_cache(maxsize=8)
def _modulation_columns_cached(n: int, fs_hz: float, modulation_hz: float,
                               harmonics: tuple[int, ...]) -> np.ndarray:
    """:func:`modulation_columns`, cached read-only: step 1 starts every cycle of a step at
    the same nominal frequency (the search of :mod:`torquemod.processing.speedmodel` looks
    up that one only)."""
    out = modulation_columns(n, fs_hz, modulation_hz, harmonics)
    out.setflags(write=False)
    return out


def _modulation_columns_many(n: int, fs_hz: float, frequencies_hz, harmonics: tuple[int, ...] = ()
                            ) -> np.ndarray:
    """:func:`modulation_columns` at each of ``frequencies_hz`` [Hz], side by side (the same
    numbers: each element is the same product and the same ``cos`` or ``sin``), in one
    vectorised evaluation."""
    t = (np.arange(n) - (n - 1) / 2) / fs_hz
    ks = (1, *harmonics)
    # k*w per (frequency, order) as modulation_columns forms it: (k*w)*t, w = 2*pi*f
    kw = np.array([k * (2 * np.pi * f) for f in frequencies_hz for k in ks])
    arg = t[:, None] * kw[None, :]
    out = np.empty((n, 2 * kw.size))
    out[:, 0::2] = np.cos(arg)
    out[:, 1::2] = np.sin(arg)
    return out


def modulation_harmonics(modulation_hz: float, fs_hz: float, n_samples: int,
                         highest: int, *, above_hz: float, avoid_hz=()) -> tuple[int, ...]:
    """Harmonics of the modulation fitted beside it.

    k = 2..``highest``: those below 0.45 x the sample rate, above the slow band and more than
    two frequency resolutions away from every frequency in ``avoid_hz`` (the fitted rotation
    orders, which would alias them). The wheel's answer to the modulation is not a pure
    sinusoid: where the creep curve bends, the creepage swing meets a changing slope and the
    wheel speed and the shaft torque carry 2nd and 3rd harmonics (1-3 % of the fundamental
    at 1 Hz on the V-Track twin at 60-90 % utilisation). Over a record holding a fractional
    number of periods they are not orthogonal to the slow basis, and, left out of the edge
    padding, they step at the record's ends, where the narrow band-pass rings: together up to
    0.3 deg at 1 Hz.

    Parameters
    ----------
    modulation_hz : float
        Modulation frequency [Hz].
    fs_hz : float
        Sample rate [Hz].
    n_samples : int
        Record length [-] (the resolution fs/n).
    highest : int
        Highest harmonic [-].
    above_hz : float
        Top of the slow band [Hz].
    avoid_hz : sequence of float
        Frequencies to keep clear of [Hz]. Default ().

    Returns
    -------
    tuple of int
        The harmonics k.

    Examples
    --------
    >>> modulation_harmonics(2.0, 53.344, 320, 3, above_hz=1.2)
    (2, 3)
    """
    resolution = fs_hz / n_samples
    kept = []
    for k in range(2, int(highest) + 1):
        f = k * modulation_hz
        if above_hz < f < 0.45 * fs_hz:
            for g in avoid_hz:
                if not abs(f - g) > 2 * resolution:
                    break
            else:
                kept.append(k)
    return tuple(kept)


#: the records whose orders and harmonics the chain removes (steps 3-5), computed with the
#: fit; the other parts on demand (:meth:`SpeedModel.part`, the same numbers)
_FILTERED = ("wheel_speed_rad_s", "torque_nm")


def fit_speed_model(channels: dict[str, np.ndarray], fs_hz: float, modulation_hz: float,
                    slow: np.ndarray, orders: np.ndarray, harmonics: tuple[int, ...] = (), *,
                    basis_t: np.ndarray | None = None, columns: np.ndarray | None = None
                    ) -> SpeedModel:
    """Least-squares fit of :class:`SpeedModel` to every channel at once.

    Time is referenced to the record's middle so the modulation's phase is decoupled from its
    frequency; the modulation's harmonics are the last columns.

    Parameters
    ----------
    channels : dict of str to ndarray
        The channels (SI units), of equal length.
    fs_hz : float
        Sample rate [Hz].
    modulation_hz : float
        Modulation frequency [Hz].
    slow : ndarray
        The slow basis (:func:`~torquemod.dsp.basis.slow_basis`).
    orders : ndarray
        The rotation-order columns.
    harmonics : tuple of int
        The modulation's harmonics (:func:`modulation_harmonics`). Default ().
    basis_t : ndarray or None
        ``Q_B'`` of an orthonormal basis of ``[slow, orders]`` (``p x n``): the noise
        statistic :meth:`SpeedModel.noise_depletion` with this ``basis_t`` is made with the
        fit. Default None.
    columns : ndarray or None
        The channels already side by side, ``(n, len(channels))`` in the order of
        ``channels`` (the same numbers; a caller that holds them stacked spares the copy
        column by column). Default None.

    Returns
    -------
    SpeedModel
        The fitted model.
    """
    names = tuple(channels)
    n = slow.shape[0]
    n_s, n_o, n_h = slow.shape[1], orders.shape[1], 2 * len(harmonics)
    if columns is not None and columns.shape == (n, len(names)) \
            and columns.flags.c_contiguous:
        y = columns
    else:
        rows = [channels[k] for k in names]
        y = np.empty((n, len(rows)), dtype=np.result_type(*rows))
        for j, r in enumerate(rows):  # np.column_stack's array, without its per-call work
            y[:, j] = r
    blas = numpyblas.addresses()
    if blas is not None and n > 1 and y.dtype == np.float64:
        # the modulation's columns, the design, its factor, the coefficients, the parts, the
        # slow parts' means and the noise statistics in one compiled call, with the numbers
        # of the route below and of SpeedModel's methods (numpy's BLAS calls)
        bounds, wanted, slots = _parts_wanted(names, n_s, n_o, n_h)
        qt, v, v_power = _noise_inputs(n, float(fs_hz), float(modulation_hz), n_s + n_o,
                                       basis_t)
        (design, dn, scale, gram, factor, coef, parts, ratio, status, means, noise,
         made) = jointfit.fit_tone_model(
            y, float(fs_hz), float(modulation_hz), _tone_orders(tuple(harmonics)), slow,
            orders, bounds, wanted, qt, v, v_power, *blas, *lstsq.lapack_addresses())
        if status == 0:
            for a in (design, dn, scale, gram, factor, coef, parts):
                a.setflags(write=False)
            model = SpeedModel(modulation_hz, fs_hz, design, n_s, coef, names,
                               lstsq.LstsqFactor(dn, scale, factor, gram), n_h)
            got = model._parts
            for i, j, key in slots:
                got[key] = parts[i, j]
            for name, m in zip(names, means.tolist(), strict=True):  # every mean
                got[(name, "mean")] = m  # (mean's numbers)
            got["variance_ratio"] = float(ratio)  # (variance_factor's)
            if made:  # (noise_depletion's, for this basis_t)
                got["noise_kept"] = (basis_t, float(noise))
            return model
    mod = modulation_columns(n, fs_hz, modulation_hz, harmonics)
    # [cos, sin, slow, orders, harmonics]
    design = np.empty((n, 2 + n_s + n_o + n_h))
    design[:, :2] = mod[:, :2]
    design[:, 2:2 + n_s] = slow
    design[:, 2 + n_s:2 + n_s + n_o] = orders
    design[:, 2 + n_s + n_o:] = mod[:, 2:]
    fac = filters.LstsqFactor.of(design, keep_gram=True)  # the model's statistics reuse it
    coef = fac.solve(y) if fac is not None else filters.lstsq(design, y)[0]
    return SpeedModel(modulation_hz, fs_hz, design, n_s, coef, names, fac, n_h)


_NO_NOISE = (np.empty((0, 0)), np.empty((0, 0)), np.empty(0))
for _a in _NO_NOISE:
    _a.setflags(write=False)


def _noise_inputs(n: int, fs_hz: float, modulation_hz: float, n_basis: int,
                  basis_t: np.ndarray | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`fit_speed_model`'s arguments of the noise statistic: ``basis_t`` (C order),
    the Hann-windowed Fourier vectors of the bins near the modulation and their squared
    norms (:meth:`SpeedModel.noise_depletion`'s, at its default half-width); empty arrays
    where it would not use ``basis_t`` (none, another shape, fewer than two bins)."""
    if basis_t is None or basis_t.shape != (n_basis, n):
        return _NO_NOISE
    sel = _bins_near(n, fs_hz, modulation_hz, NOISE_HALF_WIDTH_HZ)
    if len(sel) < 2:
        return _NO_NOISE
    v, v_power = _hann_fourier(n, sel)
    return np.ascontiguousarray(basis_t, dtype=np.float64), v, v_power


@functools.lru_cache(maxsize=16)
def _parts_wanted(names: tuple[str, ...], n_slow: int, n_orders: int, n_harmonic: int
                  ) -> tuple[np.ndarray, np.ndarray, tuple[tuple[int, int, tuple], ...]]:
    """:func:`fit_speed_model`'s column bounds of the slow part, the orders and the
    harmonics, and which parts of which channel its compiled fit forms: every channel's
    slow part (its step-8 mean), the orders and harmonics of the records the chain filters
    (:data:`_FILTERED`); and the same as ``(i, j, (name, part))`` slots of the model's
    parts. Cached read-only (the same for every cycle of a recording)."""
    end = 2 + n_slow + n_orders
    bounds = np.array([[2, 2 + n_slow], [2 + n_slow, end], [end, end + n_harmonic]])
    wanted = np.zeros((3, len(names)), dtype=bool)
    wanted[0] = True
    wanted[1:, [j for j, k in enumerate(names) if k in _FILTERED]] = True
    for a in (bounds, wanted):
        a.setflags(write=False)
    slots = tuple((i, j, (name, which)) for j, name in enumerate(names)
                  for i, which in enumerate(("slow", "orders", "harmonics")) if wanted[i, j])
    return bounds, wanted, slots
