"""The per-cycle steps of the V-Track processing chain (Section 2.4 of the paper).

Pure functions over one cycle's samples; the orchestration over an experiment is in
:mod:`torquemod.pipeline`.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field

import numpy as np
from scipy.signal import get_window

from .config import ProcessingConfig
from .data import Recording, Rig
from .dsp import filters
from .dsp.align import alignment_lag
from .dsp.basis import needs_wide_band
from .dsp.phase import SineFitResult, local_noise_psd, peak_valley_phase, sinefit_phase
from .dsp.spectrum import peak_frequency
from .errors import InputError, ProcessingError


@dataclass
class CycleSignals:
    """One cycle after steps 1-5 and 8: resampled/notched/filtered signals on a uniform grid
    at ``fs_hz`` [Hz], the peak frequencies [Hz] and the creep-curve point."""

    fs_hz: float
    t0_s: float  # time of the first resampled sample after the cycle start [s]
    torque_peak_hz: float
    wheel_peak_hz: float
    modulation_hz: float
    wheel_rotation_hz: float
    platform_rotation_hz: float
    torque_resampled: np.ndarray
    wheel_resampled: np.ndarray
    torque_notched: np.ndarray
    wheel_notched: np.ndarray
    torque_filtered: np.ndarray
    wheel_filtered: np.ndarray
    creepage: float
    coa: float
    means: dict = field(default_factory=dict)
    notches_hz: dict = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)  # warnings for the user and provenance
    creepage_drift: float = float("nan")  # creepage change over the cycle [-] (slip check)
    #: torque_amplitude_nm, wheel_amplitude_rad_s, creepage_swing [-], speed_m_s [m/s],
    #: coa_torque [-], coa_source ("forces" or "torque"), slow_band_hz (the speed model's slow
    #: band's top [Hz], dsp.basis.needs_wide_band)
    extra: dict = field(default_factory=dict)


def creepage_coa(wheel_speed_rad_s: float, platform_speed_rad_s: float, fx_n: float, fy_n: float,
                 fz_n: float, *, wheel_radius_m: float, platform_radius_m: float
                 ) -> tuple[float, float]:
    """Eq. (3) and (4) of the V-Track paper from mean values:
    ``xi = (w*Rw - W*Rp)/(W*Rp)``, ``CoA = sqrt(Fx^2 + Fy^2)/Fz``."""
    v_platform = platform_speed_rad_s * platform_radius_m
    xi = (wheel_speed_rad_s * wheel_radius_m - v_platform) / v_platform
    coa = np.hypot(fx_n, fy_n) / fz_n
    return float(xi), float(coa)


def check_cycle_length(n_samples: int, fs_hz: float, f_nominal_hz: float,
                       cfg: ProcessingConfig, *, where: str) -> None:
    """A cycle must hold the phase window plus the trimmed edges."""
    need = (cfg.phase.n_periods + 2 * cfg.phase.edge_trim_periods) / f_nominal_hz
    have = n_samples / fs_hz
    if have < need:
        raise InputError(f"cycle is {have:.2f} s long, too short for {cfg.phase.n_periods} "
                         f"modulation periods after trimming {cfg.phase.edge_trim_periods} "
                         f"period(s) at each end (needs {need:.2f} s)", path=where,
                         hint="record longer cycles")


def check_operating_point(means: dict[str, float], platform_std_rad_s: float, *,
                          where: str) -> None:
    """Refuse a cycle whose means make Eq. (3) and (4) meaningless: a platform that does not
    turn (its mean speed [rad/s] within its own scatter), wheel and platform turning in
    opposite directions, or a normal force [N] that is not positive. Absent optional channels
    (platform speed, forces) are not checked."""
    w_w = means["wheel_speed_rad_s"]
    if "platform_speed_rad_s" in means:
        w_p = means["platform_speed_rad_s"]
        if not abs(w_p) > platform_std_rad_s:
            raise InputError(f"the platform is not turning (mean speed {w_p:.3g} rad/s, "
                             f"scatter {platform_std_rad_s:.3g} rad/s)", path=where,
                             channel="platform_speed_rad_s",
                             hint="record while the platform runs, or check the channel "
                             "mapping and unit in [channels]")
        if w_w * w_p < 0:
            raise InputError(f"wheel and platform speeds have opposite signs (mean {w_w:.4g} "
                             f"and {w_p:.4g} rad/s)", path=where, channel="wheel_speed_rad_s",
                             hint="flip the sign of one speed channel so both are positive "
                             "when rolling forward")
    elif not w_w:
        raise InputError("the wheel is not turning (mean speed 0 rad/s)", path=where,
                         channel="wheel_speed_rad_s", hint="record while the wheel rolls")
    fz = means.get("fz_n")
    if fz is not None and not fz > 0:
        raise InputError(f"mean normal force is {fz:.4g} N; it must be positive (compression)",
                         path=where, channel="fz_n",
                         hint="check the channel mapping, its unit and the load cell's sign")


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


#: Channels resampled in step 2 when present (the forces for their step-8 means).
_RESAMPLED = ("torque_nm", "wheel_speed_rad_s", "platform_speed_rad_s", "fx_n", "fy_n", "fz_n")


@dataclass(frozen=True)
class SpeedModel:
    """The joint least-squares model of one cycle (ours, issue 8): for every channel
    ``x = modulation + slow + orders + harmonics + residual`` with the modulation
    ``c*cos + s*sin`` at ``modulation_hz``, the slow part in
    :func:`~torquemod.dsp.filters.slow_basis`, the rotation orders in
    :func:`~torquemod.dsp.filters.order_design` and the modulation's own harmonics (the
    creep curve's bend distorts the wheel's answer; :func:`modulation_harmonics`). One
    design serves every channel, so any linear functional of it (the step-8 mean) treats a
    speed variation that wheel and platform share alike, and it cancels in the creepage of
    Eq. (3)."""

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
        c, s = self.coef[:2, self.names.index(name)]
        return float(np.hypot(c, s))

    def variance_factor(self) -> float:
        """Variance of the modulation's coefficients in this joint model over their variance
        with the modulation fitted alone (>= 1): the price in phase noise of separating the
        modulation from the slow part and the orders, at the Cramér-Rao bound of the joint
        model (white noise)."""
        d = self.design
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

    def noise_depletion(self, *, half_width_hz: float = 0.75) -> float:
        """Fraction (<= 1) of white noise's power near the modulation that the model's
        residual keeps, averaged over the bins :func:`~torquemod.dsp.phase.local_noise_psd`
        reads: ``1 - |Q^H v_f|^2/|v_f|^2`` for the Hann-windowed Fourier vector ``v_f`` of each
        bin and Q an orthonormal basis of the design. The slow basis overlaps the modulation's
        neighbourhood, so its residual understates the noise density there; dividing by this
        restores it (E[r r^T] = sigma^2 (I - H) for least squares)."""
        d = self.design
        n = d.shape[0]
        df = self.fs_hz / n
        k = np.arange(n // 2 + 1)
        off = np.abs(k * df - self.modulation_hz)
        sel = k[(off <= half_width_hz) & (off > 1.5 * df)]
        if sel.size < 2:
            return 1.0
        fac = self.factor
        if fac is not None and fac.gram is not None:  # the fit's own numbers
            dn, gram = fac.dn, fac.gram
        else:
            dn = d / np.sqrt(np.einsum("ij,ij->j", d, d))
            gram = dn.T @ dn
        v, v_power = _hann_fourier(n, tuple(int(b) for b in sel))
        try:
            chol = np.linalg.cholesky(gram)
        except np.linalg.LinAlgError:
            # a design rank deficient to rounding (the fit fell back to the SVD): Q from
            # the SVD, over its numerical rank
            u, sv, _ = np.linalg.svd(dn, full_matrices=False)
            qv = u[:, sv > sv[0] * 1e-10].T @ v
            kept = 1.0 - (qv * qv).sum(axis=0).reshape(2, -1).sum(axis=0) / v_power
            return float(np.clip(np.mean(kept), 0.05, 1.0))
        # Q = D L^-T has orthonormal columns spanning D, and Q^H v = L^-1 (D^T v): a solve with
        # the small factor instead of forming Q (the fraction kept agrees with forming Q to
        # ~4e-12 relative, measured; it scales only the standard error). Both routes go
        # through the normal equations, which square the design's condition number: against
        # an SVD of the design the fraction is off by ~1.5e-5 relative (measured on
        # tests/test_chain_speed_equivalence.py's design), and rounding-level changes of
        # the inputs move it by up to that much (the fit's own upper factor, transposed,
        # moved it by 1e-6: not used here).
        qv = np.linalg.solve(chol, dn.T @ v)  # v: the real parts, then the imaginary parts
        kept = 1.0 - (qv * qv).sum(axis=0).reshape(2, -1).sum(axis=0) / v_power
        return float(np.clip(np.mean(kept), 0.05, 1.0))

    def mean(self, name: str) -> float:
        """Step-8 mean: the record's mean less the fitted modulation and rotation orders (the
        mean of the slow part; the residual has zero mean since the constant is fitted)."""
        key = (name, "mean")
        if key not in self._parts:
            slow = self.part(name, "slow")
            self._parts[key] = float(slow.sum()) / slow.size  # np.mean's numbers, cheaper
        return self._parts[key]


def _trace_of_inverse_2x2(a: np.ndarray) -> float:
    """``trace(inv(a))`` of a 2x2 matrix: ``(a00 + a11)/det(a)``."""
    a00, a01, a10, a11 = (float(v) for v in a.ravel())
    return (a00 + a11) / (a00 * a11 - a01 * a10)


def modulation_columns(n: int, fs_hz: float, modulation_hz: float,
                       harmonics: tuple[int, ...] = ()) -> np.ndarray:
    """``cos`` and ``sin`` of ``2*pi*k*f*t`` for k = 1 and each of ``harmonics`` (in that
    order), over ``n`` samples at ``fs_hz`` [Hz] with t [s] from the record's middle (so a
    fitted phase is decoupled from a small error of the frequency)."""
    t = (np.arange(n) - (n - 1) / 2) / fs_hz
    w = 2 * np.pi * modulation_hz
    out = np.empty((n, 2 + 2 * len(harmonics)))
    for i, k in enumerate((1, *harmonics)):
        out[:, 2 * i] = np.cos(k * w * t)
        out[:, 2 * i + 1] = np.sin(k * w * t)
    return out


def modulation_harmonics(modulation_hz: float, fs_hz: float, n_samples: int,
                         highest: int, *, above_hz: float, avoid_hz=()) -> tuple[int, ...]:
    """Harmonics k = 2..``highest`` of the modulation fitted beside it (ours): those below
    0.45 x the sample rate, above the slow band (``above_hz``) and more than two frequency
    resolutions away from every frequency in ``avoid_hz`` [Hz] (the fitted rotation orders,
    which would alias them).

    The wheel's answer to the modulation is not a pure sinusoid: where the creep curve
    bends, the creepage swing meets a changing slope and the wheel speed and the shaft torque
    carry 2nd and 3rd harmonics (1-3 % of the fundamental at 1 Hz on the V-Track twin at 60-90
    % utilisation). Over a record holding a fractional number of periods they are not
    orthogonal to the slow basis, and, left out of the edge padding, they step at the
    record's ends, where the narrow band-pass rings: together up to 0.3 deg at 1 Hz.
    """
    resolution = fs_hz / n_samples
    return tuple(k for k in range(2, int(highest) + 1)
                 if above_hz < k * modulation_hz < 0.45 * fs_hz
                 and all(abs(k * modulation_hz - g) > 2 * resolution for g in avoid_hz))


def fit_speed_model(channels: dict[str, np.ndarray], fs_hz: float, modulation_hz: float,
                    slow: np.ndarray, orders: np.ndarray, harmonics: tuple[int, ...] = ()
                    ) -> SpeedModel:
    """Least-squares fit of :class:`SpeedModel` to every channel at once (time referenced to
    the record's middle so the modulation's phase is decoupled from its frequency), with
    the modulation's ``harmonics`` (:func:`modulation_harmonics`) as its last columns."""
    names = tuple(channels)
    n = slow.shape[0]
    mod = modulation_columns(n, fs_hz, modulation_hz, harmonics)
    n_s, n_o = slow.shape[1], orders.shape[1]
    # [cos, sin, slow, orders, harmonics]
    design = np.empty((n, 2 + n_s + n_o + 2 * len(harmonics)))
    design[:, :2] = mod[:, :2]
    design[:, 2:2 + n_s] = slow
    design[:, 2 + n_s:2 + n_s + n_o] = orders
    design[:, 2 + n_s + n_o:] = mod[:, 2:]
    y = np.column_stack([channels[k] for k in names])
    fac = filters.LstsqFactor.of(design, keep_gram=True)  # the model's statistics reuse it
    coef = fac.solve(y) if fac is not None else filters.lstsq(design, y)[0]
    return SpeedModel(modulation_hz, fs_hz, design, slow.shape[1], coef, names, fac,
                      2 * len(harmonics))


class _SlowOrdersRemoval:
    """Records ``y`` (columns) less the slow part and the rotation orders of the
    :class:`SpeedModel` fitted with the modulation at a frequency f: ``y - B c_B`` of the
    least-squares fit ``y ~ M c_M + B c_B`` with ``B = [slow, orders]`` and M the cos and sin
    at f and at its ``harmonics`` (time from the record's middle; the harmonics stay in the
    result). By Frisch-Waugh-Lovell, with ``r(z)`` the
    residual of z fitted on B alone, ``c_M = (r(M)'r(M))^-1 r(M)'r(y)`` and
    ``y - B c_B = r(y) + (M - r(M)) c_M``: B is factored and ``r(y)`` computed once for every
    f, and each f costs the fit of M's two columns on B (instead of a new factorisation of
    the whole design). The same numbers as :func:`fit_speed_model`'s parts to rounding
    (tests/test_chain_kernels.py)."""

    def __init__(self, y: np.ndarray, slow: np.ndarray, orders: np.ndarray, fs_hz: float,
                 harmonics: tuple[int, ...] = ()):
        self.y, self.fs_hz, self.harmonics = y, fs_hz, tuple(harmonics)
        self.slow, self.orders = slow, orders
        self.b = np.hstack([slow, orders])
        self.fac = filters.LstsqFactor.of(self.b)
        if self.fac is not None:
            self.r_y = y - self.b @ self.fac.solve(y)

    def at(self, modulation_hz: float) -> np.ndarray:
        """``y`` less its slow part and orders with the modulation at ``modulation_hz``."""
        if self.fac is None:  # (nearly) rank-deficient: the whole model, fitted by the SVD
            model = fit_speed_model({str(i): c for i, c in enumerate(self.y.T)}, self.fs_hz,
                                    modulation_hz, self.slow, self.orders, self.harmonics)
            end = model.design.shape[1] - model.n_harmonic_columns
            fit = model.design[:, 2:end] @ model.coef[2:end]
            return self.y - fit
        m = modulation_columns(self.y.shape[0], self.fs_hz, modulation_hz, self.harmonics)
        r_m = m - self.b @ self.fac.solve(m)
        c_m = np.linalg.solve(r_m.T @ r_m, r_m.T @ self.r_y)
        return self.r_y + (m - r_m) @ c_m

    def explained(self, column: int, modulation_hz: float) -> float:
        """Power of record ``column`` that the modulation (and its harmonics) at
        ``modulation_hz`` [Hz] explains beyond the slow part and the orders:
        ``r_y' r_M (r_M' r_M)^-1 r_M' r_y`` (Frisch-Waugh-Lovell, as :meth:`at`)."""
        m = modulation_columns(self.y.shape[0], self.fs_hz, modulation_hz, self.harmonics)
        r_m = m - self.b @ self.fac.solve(m)
        b = r_m.T @ self.r_y[:, column]
        return float(b @ np.linalg.solve(r_m.T @ r_m, b))

    def refine(self, column: int, peak_hz: float, *, tol_hz: float = 1e-6) -> float:
        """The frequency [Hz] near ``peak_hz`` at which the model explains most of record
        ``column``: the least-squares (for white noise, maximum-likelihood) frequency of the
        modulation beside the slow part and the orders (variable projection, Golub and
        Pereyra 1973). A plain spectral peak of the record less a slow part fitted at another
        frequency is pulled towards that frequency (by up to 0.9 mHz at 1 Hz on a 6.5 s
        record) and carries the window's own bias from the modulation's negative-frequency
        image; this maximum has neither: on a noise-free record it is the modulation's
        frequency.

        Parabolic steps through three values of the explained power, 0.05/T, 0.005/T and
        0.0005/T apart (T the record's duration), each from the previous vertex, until a step
        is below ``tol_hz``: near its maximum the explained power is a parabola to
        (pi*h*T)^2/3 relative, so each step leaves ~2 % of the previous offset at the first
        spacing and 0.03 % at the next. A smooth function of the record (unlike a bracketing
        search, whose stopping point moves within its tolerance with rounding-level changes
        of the input). ``peak_hz`` itself when the design is (nearly) rank deficient."""
        if self.fac is None:
            return peak_hz
        duration = self.y.shape[0] / self.fs_hz
        f = float(peak_hz)
        for h in (0.05 / duration, 0.005 / duration, 0.0005 / duration):
            e_lo, e_0, e_hi = (self.explained(column, f + k * h) for k in (-1.0, 0.0, 1.0))
            curvature = e_lo - 2.0 * e_0 + e_hi
            if not curvature < 0:  # not near a maximum: keep the spectral peak's value
                return float(peak_hz)
            step = float(np.clip(0.5 * h * (e_lo - e_hi) / curvature, -2.0 * h, 2.0 * h))
            f += step
            if abs(step) < tol_hz:
                break
        return f


def tracked_orders(speed_rad_s: np.ndarray, fs_hz: float, slow: np.ndarray,
                   harmonics: tuple[int, ...], *, above_hz: float, avoid_hz: float,
                   modulation_hz: float | None = None) -> tuple[np.ndarray, float]:
    """Columns of an encoder's eccentricity at the rotation orders ``harmonics`` that lie above
    the slow band (``above_hz``), below 0.45 x the sample rate, clear of the modulation at
    ``avoid_hz`` [Hz] and not already spanned by the slow basis (:func:`_separable_orders`);
    and the mean rotation frequency [Hz].

    An eccentric encoder reads ``w*(1 + e(theta))``: its error follows the angle and scales
    with the speed. The columns are ``(w_s/mean w_s)*cos(k*theta)``, ``... sin(k*theta)``
    with ``w_s`` the slow part of the speed (least squares on ``slow`` jointly with the
    modulation at ``modulation_hz``, which then cannot leak into it) and ``theta`` its
    integral, so they follow a wobble or a ramp (order tracking) and do not carry the
    modulation's own phase wobble into the angle.
    """
    base = _order_base(speed_rad_s.size, fs_hz, slow, modulation_hz)
    return _tracked_orders(speed_rad_s, fs_hz, slow, harmonics, base, None,
                           above_hz=above_hz, avoid_hz=avoid_hz)


def _order_base(n: int, fs_hz: float, slow: np.ndarray, modulation_hz: float | None
                ) -> np.ndarray:
    """The columns :func:`tracked_orders` fits before any order: the slow basis, and the
    modulation at ``modulation_hz`` when given; C order, the layout ``lstsq`` receives in
    :func:`_tracked_orders` (BLAS sums a Fortran-ordered design's normal matrix in another
    order, which changes the last bits)."""
    if modulation_hz is None:
        return np.ascontiguousarray(slow)
    t = np.arange(n) / fs_hz
    w = 2 * np.pi * modulation_hz
    return np.ascontiguousarray(np.column_stack([slow, np.cos(w * t), np.sin(w * t)]))


def _tracked_orders(speed_rad_s: np.ndarray, fs_hz: float, slow: np.ndarray,
                    harmonics: tuple[int, ...], base: np.ndarray,
                    base_factor: filters.LstsqFactor | None, *, above_hz: float,
                    avoid_hz: float) -> tuple[np.ndarray, float]:
    """:func:`tracked_orders` with its first design ``base`` given, and that design's
    least-squares factor when already computed (wheel and platform share both)."""
    resolution = fs_hz / speed_rad_s.size
    cols = np.empty((speed_rad_s.size, 0))
    f_rot = float("nan")
    for it in range(2):  # the slow part is refitted with the first pass's orders
        if it == 0 and base_factor is not None:
            coef = base_factor.solve(speed_rad_s)
        else:
            coef, _ = filters.lstsq(np.column_stack([base, cols]), speed_rad_s)
        w_s = slow @ coef[:slow.shape[1]]
        mean = float(w_s.sum()) / w_s.size  # np.mean's numbers
        f_rot = abs(mean) / (2 * np.pi)
        kept = [h for h in harmonics if above_hz < h * f_rot < 0.45 * fs_hz
                and abs(h * f_rot - avoid_hz) > 2 * resolution]
        if not kept or mean == 0:
            return np.empty((speed_rad_s.size, 0)), f_rot
        cols = filters.order_design(filters.unwrapped_angle(w_s, fs_hz), kept) \
            * (w_s / mean)[:, None]
        cols = _separable_orders(cols, base, base_factor)
        if not cols.shape[1]:
            return cols, f_rot
    return cols, f_rot


#: an order's columns whose residual on the slow basis and the modulation keeps less than
#: this fraction of their norm are left to the slow basis (:func:`_separable_orders`)
ORDER_MIN_RESIDUAL = 0.1


def _separable_orders(cols: np.ndarray, base: np.ndarray,
                      base_factor: filters.LstsqFactor | None) -> np.ndarray:
    """The pairs of order columns ``cols`` (cos, sin per order) that the first design
    ``base`` (slow basis and modulation) does not already span: an order is kept when the
    least-squares residual of each of its columns on ``base`` keeps at least
    :data:`ORDER_MIN_RESIDUAL` of the column's norm.

    The slow basis's Slepian sequences (Slepian 1978) and polynomials reach about two frequency
    resolutions above the slow band's nominal top (a tone one resolution above it keeps
    ~1e-3 of its norm, a tone 0.01 resolution above it ~1e-6). An order that close to the
    band is a slow variation over this record: fitted beside the slow basis as well, the
    joint design is rank deficient to rounding (variance inflation ``1/r**2`` for a
    residual fraction r), the split between the slow part and the order is arbitrary, and
    so is every channel's step-8 mean, the slow part's mean (a V-Track platform turning at
    0.188 Hz on a one-revolution cycle with the slow band's top at 0.186 Hz gave a mean
    normal force of -1110 N on a 4200 N record). Left out, the slow basis models it.
    """
    if not cols.shape[1]:
        return cols
    fit = base_factor.solve(cols) if base_factor is not None else filters.lstsq(base, cols)[0]
    res = cols - base @ fit
    frac = np.sqrt(np.einsum("ij,ij->j", res, res) / np.einsum("ij,ij->j", cols, cols))
    keep = np.repeat(frac.reshape(-1, 2).min(axis=1) >= ORDER_MIN_RESIDUAL, 2)
    return cols if keep.all() else np.ascontiguousarray(cols[:, keep])


def _coa_from_torque(model: SpeedModel, fs_hz: float, *, wheel_radius_m: float,
                     normal_load_n: float | None, inertia_kg_m2: float | None) -> float:
    """The adhesion the drive uses, ``(T_dc - J*dw/dt)/(N*Rw)`` [-]: the mean torque less
    the torque that accelerated the wheel over the cycle (J [kg m^2] when the rig gives it;
    the slow part's change of speed over the record), over N [N] times Rw [m]. It ignores
    bearing and rolling losses and the lateral share (see docs/format.md)."""
    if not normal_load_n:
        return float("nan")
    w_slow = model.part("wheel_speed_rad_s", "slow")
    accel = (w_slow[-1] - w_slow[0]) / (w_slow.size / fs_hz)
    torque = model.mean("torque_nm") - (inertia_kg_m2 or 0.0) * accel
    return float(torque / (normal_load_n * wheel_radius_m))


#: The slow band's top stays at least this many frequency resolutions (1/T, T the cycle's
#: duration) below the nominal modulation frequency. Its extra Slepian sequences reach
#: beyond it, and a slow basis that overlaps the modulation's main lobe makes the joint fit
#: nearly collinear: at 0.5 Hz on a 14 s record the scaled 0.3 Hz band (2.8 resolutions
#: away) left 0.05 deg on noise-free records at 90 % of the peak, 0.2 Hz 0.007 deg
#: (tests/test_chain_orbit.py). At 2 Hz on a V-Track cycle the limit (1.34 Hz) lies above
#: the default 1.2 Hz and changes nothing.
SLOW_GAP_RESOLUTIONS = 4.0


def _slow_and_orders(wheel: np.ndarray, platform: np.ndarray | None, fs_hz: float,
                     f_start_hz: float, max_hz: float, cfg: ProcessingConfig
                     ) -> tuple[np.ndarray, np.ndarray, list[float]]:
    """The speed model's slow basis up to ``max_hz`` [Hz], the tracked rotation orders of
    both speeds above it and their frequencies [Hz] (:func:`tracked_orders`)."""
    n, nq = wheel.size, cfg.notch
    slow = filters.slow_basis(n, fs_hz, max(max_hz, 0.0), extra=cfg.slow.extra_sequences,
                              degree=cfg.slow.polynomial_degree)
    cols, rotation_hz = [], []
    base = _order_base(n, fs_hz, slow, f_start_hz)  # the same first design for both speeds
    base_factor = filters.LstsqFactor.of(base)
    for speed, harmonics in ((wheel, nq.wheel_harmonics), (platform, nq.platform_harmonics)):
        if speed is not None:
            c, f_rot = _tracked_orders(speed, fs_hz, slow, harmonics, base, base_factor,
                                       above_hz=max_hz, avoid_hz=f_start_hz)
            cols.append(c)
            rotation_hz += [h * f_rot for h in harmonics]
    return slow, np.column_stack(cols), rotation_hz


def process_cycle(rec: Recording, rig: Rig, cfg: ProcessingConfig, *, where: str,
                  nominal_hz: float | None = None, normal_load_n: float | None = None
                  ) -> CycleSignals:
    """Steps 1-5 and 8 on one cycle of a recording.

    ``nominal_hz`` [Hz] is the manifest's modulation frequency (a starting value for step 1;
    default the middle of the search band); ``normal_load_n`` [N] the nominal load for the
    torque-based CoA. Optional channels (platform speed, forces) may be absent: without the
    platform speed no creepage is measured, without forces the CoA is the torque-based one.
    """
    fs = rec.fs_hz
    up, down = filters.resample_ratio(fs, cfg.resample.target_hz,
                                      max_denominator=cfg.resample.max_denominator)
    fs_r = fs * up / down
    if fs < cfg.resample.target_hz:
        raise InputError(f"sample rate {fs:.6g} Hz is below the chain's resampling rate "
                         f"{cfg.resample.target_hz} Hz", path=where, channel="time_s",
                         hint="record at a higher rate or lower [processing] resample.target_hz")
    ch = rec.channels
    names = [k for k in _RESAMPLED if k in ch]
    # Step 2 (done first: step 1's spectral peak is the same on the resampled record, whose
    # anti-alias filter is flat across the search band, and costs 300x less there). The
    # output samples the FIR's zero padding touches are cut off.
    edge = filters.resampler_edge_samples(up, down)
    resampled, full_means = filters.resample_rows([ch[k] for k in names], up, down,
                                                  kaiser_beta=cfg.resample.kaiser_beta,
                                                  method=cfg.resample.method,
                                                  padtype="constant", return_means=True)
    resampled = resampled[:, edge:-edge]  # the zero padding touched only the cut samples
    sig = dict(zip(names, resampled, strict=True))
    n = resampled.shape[1]
    if n < 8:
        raise InputError(f"only {n} samples after resampling to {fs_r:.4g} Hz",
                         path=where, hint="the recording is too short")
    tq, wh = sig["torque_nm"], sig["wheel_speed_rad_s"]
    pl = sig.get("platform_speed_rad_s")
    nq, fp = cfg.notch, cfg.frequency
    # The speed model (ours): slow variation, rotation orders that follow the integrated
    # angles, and the modulation, fitted jointly (SpeedModel).
    f_start = nominal_hz if nominal_hz is not None else 0.5 * sum(fp.band_hz)
    # the slow band stops SLOW_GAP_RESOLUTIONS frequency resolutions below the modulation
    top = f_start - SLOW_GAP_RESOLUTIONS * fs_r / n
    max_hz = min(cfg.slow.max_hz, top) if cfg.slow.enabled else 0.0
    quiet_hz = min(cfg.slow.quiet_max_hz, top)
    if cfg.slow.enabled and 0.0 < quiet_hz < max_hz and not needs_wide_band(
            wh, pl, fs_r, f_start, quiet_hz, max_hz, extra=cfg.slow.extra_sequences,
            degree=cfg.slow.polynomial_degree):
        max_hz = quiet_hz  # the narrower band: no speed variation above it (needs_wide_band)
    slow, orders, rotation_hz = _slow_and_orders(wh, pl, fs_r, f_start, max_hz, cfg)
    mod_harmonics = modulation_harmonics(f_start, fs_r, n, cfg.slow.modulation_harmonics,
                                         above_hz=max_hz, avoid_hz=rotation_hz)
    # Step 1: modulation frequency = mean of the torque's and wheel speed's peaks, taken on
    # the records less their slow part and rotation orders (their leakage would pull the
    # peak); twice, since the model's modulation term starts from the nominal frequency.
    # Each peak is then refined to the frequency at which the speed model explains most of
    # the channel (_SlowOrdersRemoval.refine): the slow basis absorbs part of a mismatched
    # modulation and pulls the plain peak towards the frequency assumed.
    f_mod = f_start
    peaks: dict[str, float] = {}
    cleaner = _SlowOrdersRemoval(np.column_stack([tq, wh]), slow, orders, fs_r, mod_harmonics)
    for _ in range(2):
        cleaned = cleaner.at(f_mod)
        for i, name in enumerate(("torque_nm", "wheel_speed_rad_s")):
            try:
                peaks[name] = peak_frequency(cleaned[:, i], fs_r, band_hz=fp.band_hz,
                                             window=fp.window, detrend=fp.detrend,
                                             zero_pad=fp.zero_pad)
            except ProcessingError as exc:
                raise InputError(f"no modulation found: {exc}", path=where, channel=name,
                                 hint="check the modulation was on and [processing] "
                                 "frequency.band_hz") from None
        f_mod = 0.5 * (peaks["torque_nm"] + peaks["wheel_speed_rad_s"])
    if fp.refine:
        for i, name in enumerate(("torque_nm", "wheel_speed_rad_s")):
            peaks[name] = cleaner.refine(i, peaks[name], tol_hz=fp.tolerance_hz)
        f_mod = 0.5 * (peaks["torque_nm"] + peaks["wheel_speed_rad_s"])
    if fp.common == "torque":
        f_mod = peaks["torque_nm"]
    model = fit_speed_model(sig, fs_r, f_mod, slow, orders, mod_harmonics)
    f_t, f_w = peaks["torque_nm"], peaks["wheel_speed_rad_s"]
    f_wheel = abs(model.mean("wheel_speed_rad_s")) / (2 * np.pi)
    f_plat = abs(model.mean("platform_speed_rad_s")) / (2 * np.pi) if pl is not None \
        else float("nan")
    wheel_notches = filters.notch_frequencies(f_wheel, nq.wheel_harmonics, fs_r)
    plat_notches = filters.notch_frequencies(f_plat, nq.platform_harmonics, fs_r) \
        if pl is not None else []
    # Step 3: notches at the wheel's rotation harmonics, zero phase (platform: see step 8),
    # on the records less their slow part and orders.
    notes = [f"{where}: wheel-speed notch at {f0:.3f} Hz lies within {nq.warn_within_hz} Hz "
             f"of the modulation frequency {f_mod:.3f} Hz; it also attenuates the modulation"
             for f0 in wheel_notches if abs(f0 - f_mod) < nq.warn_within_hz]
    hp = filters.design_highpass(cfg.highpass.cutoff_hz, cfg.highpass.order, fs_r)
    bp = filters.design_bandpass(f_mod, cfg.bandpass.width_hz, cfg.bandpass.order, fs_r)
    notch_ba = {f0: filters.design_notch(f0, nq.q, fs_r) for f0 in wheel_notches}
    pad = max(filters.settling_samples(ba) for ba in [hp, bp, *notch_ba.values()])
    tones = [f_mod, *wheel_notches]

    (wh_p, wh_level, _), (tq_p, tq_level, _) = filters.model_padded_rows(
        [sig[k] - model.part(k, "slow") - model.part(k, "orders") - model.part(k, "harmonics")
         for k in ("wheel_speed_rad_s", "torque_nm")], fs_r, tones, pad)
    # the wheel speed through its notches, then both records through the high-pass and the
    # band-pass together (one lfilter call per filter and direction for both rows)
    wh_p = filters.zero_phase_cascade([notch_ba[f0] for f0 in wheel_notches], wh_p)
    both_f = filters.zero_phase_cascade([hp, bp], np.vstack([wh_p, tq_p]))
    wh_n = wh_p[pad:pad + n] + wh_level + model.mean("wheel_speed_rad_s")
    tq_n = tq_p[pad:pad + n] + tq_level + model.mean("torque_nm")
    wh_f, tq_f = both_f[0, pad:pad + n], both_f[1, pad:pad + n]
    # Step 8: creepage and CoA from means, each the mean of the channel less its fitted
    # modulation and rotation orders (SpeedModel.mean): the value the notched signal averages
    # to, free of the partial modulation period a cycle holds and of edge transients, and
    # taken through one model for every channel.
    means = {k: model.mean(k) for k in names}
    means["torque_nm"] = float(full_means[names.index("torque_nm")])  # the raw record's
    check_operating_point(means, float(np.std(pl)) if pl is not None else 0.0, where=where)
    has_forces = all(k in sig for k in ("fx_n", "fz_n"))
    inertia = rig.extra.get("wheel_inertia_kg_m2") if isinstance(rig.extra, dict) else None
    coa_t = _coa_from_torque(model, fs_r, wheel_radius_m=rig.wheel_radius_m,
                             normal_load_n=normal_load_n, inertia_kg_m2=inertia)
    if pl is not None:
        xi, drift = creepage_and_drift(model, fs_r, wheel_radius_m=rig.wheel_radius_m,
                                       platform_radius_m=rig.platform_radius_m,
                                       platform_harmonics=nq.platform_harmonics)
        speed = abs(means["platform_speed_rad_s"]) * rig.platform_radius_m
    else:
        xi, drift = float("nan"), float("nan")
        speed = abs(means["wheel_speed_rad_s"]) * rig.wheel_radius_m
    coa = float(np.hypot(means["fx_n"], means.get("fy_n", 0.0)) / means["fz_n"]) \
        if has_forces else coa_t
    wheel_amp = model.amplitude("wheel_speed_rad_s")
    out = CycleSignals(fs_r, edge / fs_r, f_t, f_w, f_mod, f_wheel, f_plat, tq, wh,
                       tq_n, wh_n, tq_f, wh_f, xi, coa, means,
                       {"wheel": wheel_notches, "platform": plat_notches}, notes,
                       creepage_drift=drift)
    out.extra.update({"speed_model": model, "slow_band_hz": float(max_hz),
                      "variance_factor": model.variance_factor(),
                      "noise_kept": model.noise_depletion(),
                      "torque_amplitude_nm": model.amplitude("torque_nm"),
                      "wheel_amplitude_rad_s": wheel_amp,
                      "creepage_swing": wheel_amp * rig.wheel_radius_m / speed,
                      "speed_m_s": speed, "coa_torque": coa_t,
                      "coa_source": "forces" if has_forces else "torque"})
    return out


def creepage_and_drift(model: SpeedModel, fs_hz: float, *, wheel_radius_m: float,
                       platform_radius_m: float, platform_harmonics: tuple[int, ...]
                       ) -> tuple[float, float]:
    """Creepage of Eq. (3) [-] and its change over the record [-], from the slow parts of the
    wheel and platform speeds (:class:`SpeedModel`).

    The ratio ``q(t) = W(t)*Rp/(w(t)*Rw) = (1 + e(theta_p))/(1 + xi(t))`` is free of any speed
    variation that wheel and platform share; the platform encoder's eccentricity ``e`` (at its
    revolution harmonics, inside the slow band, inseparable from a real once-per-revolution
    wobble in the platform channel alone) enters it linearly. A least-squares fit
    ``q ~ c0 + c1*(t - mean t) + sum(a_k cos + b_k sin)(k*theta_p)`` gives
    ``xi = 1/c0 - 1`` and the drift ``-c1*T/c0^2``: a wheel that follows a moving platform
    keeps its creepage; a wheel that starts to slip shows a creepage rising within the cycle.
    """
    w = model.part("wheel_speed_rad_s", "slow")
    p = model.part("platform_speed_rad_s", "slow")
    if np.any(w == 0):
        return float("nan"), float("nan")
    q = p * platform_radius_m / (w * wheel_radius_m)
    n = q.size
    t = np.arange(n) / fs_hz
    c0 = float(q.sum()) / n  # np.mean's numbers
    design = np.empty((n, 2 + 2 * len(platform_harmonics)))  # [1, t - mean t, orders]
    design[:, 0] = 1.0
    design[:, 1] = t - t.mean()
    for _ in range(2):
        # the platform's true angle from the wheel's speed (free of the platform encoder's
        # own error, whose square would otherwise bias c0 by e^2/2)
        theta = filters.unwrapped_angle(w * c0 * wheel_radius_m / platform_radius_m, fs_hz)
        kept = [k for k in platform_harmonics if k * abs(theta[-1]) / (2 * np.pi) > 0.5]
        design[:, 2:2 + 2 * len(kept)] = filters.order_design(theta, kept)
        coef, _ = filters.lstsq(design[:, :2 + 2 * len(kept)], q)
        c0, c1 = float(coef[0]), float(coef[1])
    return 1.0 / c0 - 1.0, -c1 * (n / fs_hz) / c0**2


def align_lags(cycles: list[CycleSignals], cfg: ProcessingConfig) -> list[int]:
    """Step 6: lag [samples] of each cycle's band-passed torque against the first cycle's."""
    if not cfg.align.enabled or len(cycles) < 2:
        return [0] * len(cycles)
    ref = cycles[0]
    max_lag = round(cfg.align.max_lag_periods * ref.fs_hz / ref.modulation_hz)
    return [0] + [alignment_lag(ref.torque_filtered, c.torque_filtered, max_lag)
                  for c in cycles[1:]]


def model_phase(model: SpeedModel, torque: np.ndarray, wheel: np.ndarray, fs_hz: float
                ) -> SineFitResult:
    """The sine fit as the joint speed model itself (the least-squares estimate of the
    modulation beside the slow part and the orders): lag ``phi_T - phi_W`` [deg] with the
    standard error of :func:`~torquemod.dsp.phase.sinefit_phase` from the model's residual."""
    n = model.design.shape[0]
    phases, amps, var = [], [], 0.0
    for name, x in (("torque_nm", torque), ("wheel_speed_rad_s", wheel)):
        j = model.names.index(name)
        c, s = model.coef[:2, j]
        resid = x - model.design @ model.coef[:, j]
        var += local_noise_psd(resid, fs_hz, model.modulation_hz) / ((c * c + s * s) * n / fs_hz)
        phases.append(float(np.arctan2(-s, c)))
        amps.append(float(np.hypot(c, s)))
    lag = float(np.degrees(np.angle(np.exp(1j * (phases[0] - phases[1])))))
    return SineFitResult(lag, float(np.degrees(np.sqrt(var))), amps[0], amps[1], phases[0],
                         phases[1], n, (0.0, n / fs_hz))


#: The paper's peak/valley estimator over its three middle periods scatters 1.21-1.32 times
#: the Cramér-Rao bound where the sine fit reaches 0.97-1.07 of it (benchmarks/phase_accuracy.py):
#: its standard error is taken as this factor times the sine fit's on the same data. Over the
#: whole cycle (``phase.paper_window = "cycle"``) it scatters 0.98-1.14 times the bound, so
#: the factor errs on the safe side there.
PAPER_SE_FACTOR = 1.3


def cycle_phase(c: CycleSignals, cfg: ProcessingConfig, *, center_index: float
                ) -> tuple[float, float, tuple[float, float]]:
    """Step 7: (phase [deg], standard error [deg], window [s]) of one cycle.

    ``center_index`` is where the phase window is centred (the aligned middle).
    """
    n = c.torque_filtered.size
    period_n = c.fs_hz / c.modulation_hz
    nuisance = tuple(c.notches_hz["wheel"]) + tuple(c.notches_hz["platform"])
    if cfg.phase.sinefit_input == "model" and "speed_model" in c.extra:
        fit = model_phase(c.extra["speed_model"], c.torque_resampled, c.wheel_resampled,
                          c.fs_hz)
    elif cfg.phase.sinefit_input == "bandpassed":
        fit = sinefit_phase(c.torque_filtered, c.wheel_filtered, c.fs_hz, c.modulation_hz,
                            nuisance_hz=nuisance, trend=cfg.phase.sinefit_trend,
                            noise_from=(c.torque_notched, c.wheel_notched))
    else:
        fit = sinefit_phase(c.torque_notched, c.wheel_notched, c.fs_hz, c.modulation_hz,
                            nuisance_hz=nuisance, trend=cfg.phase.sinefit_trend)
    # the speed model's removal costs the modulation this much variance, and its fitted
    # columns leave the residual's noise density near the modulation too small (SpeedModel)
    se_fit = fit.phase_stderr_deg * np.sqrt(c.extra.get("variance_factor", 1.0)
                                            / c.extra.get("noise_kept", 1.0))
    if cfg.phase.method == "sinefit":
        return fit.phase_deg, float(se_fit), fit.window_s
    n_periods = cfg.phase.n_periods
    if cfg.phase.paper_window == "cycle":  # every whole period between the trimmed edges
        n_periods = max(n_periods, int(np.floor(n / period_n + 1e-9
                                                - 2 * cfg.phase.edge_trim_periods)))
    half = (n_periods / 2 + cfg.phase.edge_trim_periods) * period_n
    center = min(max(center_index, half), n - half)
    res = peak_valley_phase(c.torque_filtered, c.wheel_filtered, c.fs_hz, c.modulation_hz,
                            center_s=center / c.fs_hz, n_periods=n_periods)
    hw = n_periods / 2 / c.modulation_hz
    se = PAPER_SE_FACTOR * se_fit
    return res.phase_deg, float(se), (center / c.fs_hz - hw, center / c.fs_hz + hw)
