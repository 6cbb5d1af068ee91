"""The joint least-squares speed model of one cycle (ours, :mod:`.jointmodel`:
:class:`SpeedModel`, :func:`fit_speed_model`) and the removal of its slow part and orders
for the search of the modulation frequency (:class:`_SlowOrdersRemoval`). Used by the
per-cycle steps of :mod:`torquemod.processing.chain`.
"""

from __future__ import annotations

import numpy as np

from torquemod.dsp import blockbasis, filters, modsearch, projection, tonesearch
from torquemod.processing.jointmodel import (  # noqa: F401  (re-exported)
    SpeedModel,
    _centred_time,
    _hann,
    _hann_fourier,
    _modulation_columns_cached,
    _modulation_columns_many,
    fit_speed_model,
    modulation_columns,
    modulation_columns_reference,
    modulation_harmonics,
)

_NOT_YET = object()


class _SlowOrdersRemoval:
    """Records ``y`` (columns) less the slow part and the rotation orders of the
    :class:`~torquemod.processing.speedmodel.SpeedModel` fitted with the modulation at a
    frequency f: ``y - B c_B`` of the least-squares fit ``y ~ M c_M + B c_B`` with
    ``B = [slow, orders]`` and M the cos and sin at f and at its ``harmonics`` (time from
    the record's middle; the harmonics stay in the result). By Frisch-Waugh-Lovell, with
    ``r(z)`` the residual of z fitted on B alone, ``c_M = (r(M)'r(M))^-1 r(M)'r(y)`` and
    ``y - B c_B = r(y) + (M - r(M)) c_M``: an orthonormal basis Q of B is formed (from the
    slow basis's own, :func:`torquemod.dsp.blockbasis.removal_basis_at`, or from B's factor,
    :func:`torquemod.dsp.projection.orthonormal_basis_t`) and ``r(y)`` computed once for
    every f, and each f costs the product ``Q'M`` (``r(M) = M - Q Q'M``) instead of a new
    factorisation of the whole design. The same numbers as
    :func:`~torquemod.processing.speedmodel.fit_speed_model`'s parts to rounding
    (tests/processing/test_chain_kernels.py)."""

    def __init__(self, y: np.ndarray, slow: np.ndarray, orders: np.ndarray, fs_hz: float,
                 harmonics: tuple[int, ...] = (), *, start_hz: float | None = None):
        self.y, self.fs_hz, self.harmonics = y, fs_hz, tuple(harmonics)
        self._orders = np.array((1, *self.harmonics), dtype=np.int64)  # the tone's orders
        self.start_hz = start_hz  # the search's nominal start [Hz]: its columns cached
        self.slow, self.orders = slow, orders
        self._b = self._fac = _NOT_YET
        self.qt = self._at_start = None
        # Q from the slow basis's own (dsp.blockbasis) and, in the same compiled call, the
        # removal at the nominal frequency that the search asks for first
        tone = None if start_hz is None else _modulation_columns_cached(
            y.shape[0], float(fs_hz), float(start_hz), self.harmonics)
        block = blockbasis.removal_basis_at(y, slow, orders, tone)
        if block is not None:
            self.qt, self.r_y, self.qy, self._at_start = block
            return
        if self.fac is not None:
            # an orthonormal basis Q of B (dsp.projection): the residual is y - Q Q'y, and
            # each trial frequency costs one product with Q instead of a solve on B
            self.qt = projection.orthonormal_basis_t(self.fac)
            if self.qt is not None:
                self.r_y = y - self.qt.T @ (self.qt @ y)
                self.qy = self.qt @ self.r_y  # ~0: kept for the rounding's sake
            else:
                self.r_y = y - self.b @ self.fac.solve(y)

    def search(self, *, band_hz: tuple[float, float], window: str, detrend: str,
               zero_pad: int, refine: bool, tol_hz: float
               ) -> tuple[list[float], list[float], list[float]] | None:
        """The chain's search of the modulation frequency on two records in one compiled
        call (:func:`torquemod.dsp.modsearch.search_modulation`): the spectral peaks of
        :meth:`at` the start frequency, the peaks of :meth:`at` their mean, and those
        refined by :meth:`refine_many` (with ``refine``), the numbers of these calls one
        after the other. None where that route does not apply (no removal made with the
        basis at the start, or a step that would go another way): then call them.

        Parameters
        ----------
        band_hz, window, detrend, zero_pad
            As :func:`~torquemod.dsp.spectrum.peak_frequencies` (band [Hz]).
        refine : bool
            Whether to refine the second peaks.
        tol_hz : float
            As :meth:`refine_many` [Hz].

        Returns
        -------
        tuple of list of float or None
            Each record's first peaks, second peaks and refined ones [Hz].
        """
        if self._at_start is None or self.qt is None or self.start_hz is None \
                or self.y.shape[1] != 2:
            return None
        out = modsearch.search_modulation(
            self._at_start, float(self.start_hz), self.qt, self.r_y, self.qy,
            float(self.fs_hz), self._orders, band_hz=band_hz, window=window, detrend=detrend,
            zero_pad=zero_pad, refine=refine, tol_hz=tol_hz)
        if out is not None:
            self._at_start = None  # used, as at() hands it over once
        return out

    @property
    def b(self) -> np.ndarray:
        """The design ``B = [slow, orders]``, made when first asked for (only the routes
        without the slow basis's own Q use it)."""
        if self._b is _NOT_YET:
            self._b = np.hstack([self.slow, self.orders])
        return self._b

    @property
    def fac(self) -> filters.LstsqFactor | None:
        """B's least-squares factor (:meth:`~torquemod.dsp.lstsq.LstsqFactor.of`), made when
        first asked for: where Q comes from the slow basis's own, only the fallbacks use it."""
        if self._fac is _NOT_YET:
            self._fac = filters.LstsqFactor.of(self.b)
        return self._fac

    def at(self, modulation_hz: float) -> np.ndarray:
        """``y`` less its slow part and orders with the modulation at ``modulation_hz``."""
        if self.qt is None and self.fac is None:  # (nearly) rank-deficient: the SVD
            model = fit_speed_model({str(i): c for i, c in enumerate(self.y.T)}, self.fs_hz,
                                    modulation_hz, self.slow, self.orders, self.harmonics)
            end = model.design.shape[1] - model.n_harmonic_columns
            fit = model.design[:, 2:end] @ model.coef[2:end]
            return self.y - fit
        if self._at_start is not None and modulation_hz == self.start_hz:
            out, self._at_start = self._at_start, None  # made with the basis, handed over once
            return out
        if self.qt is not None and modulation_hz != self.start_hz:
            # the columns (modulation_columns' numbers) and the steps below in one compiled
            # call
            out = projection.removal_at_tone(self.fs_hz, modulation_hz, self._orders,
                                             self.qt, self.r_y, self.qy)
            if out is not None:
                return out
        m = _modulation_columns_cached(self.y.shape[0], float(self.fs_hz),
                                       float(modulation_hz), self.harmonics) \
            if modulation_hz == self.start_hz else \
            modulation_columns(self.y.shape[0], self.fs_hz, modulation_hz, self.harmonics)
        if self.qt is not None:  # the steps below in one compiled call (the same numbers)
            out = projection.removal_at(m, self.qt, self.r_y, self.qy)
            if out is not None:
                return out
        if self.qt is not None:  # y - B c_B = r_y + Q Q'M c_M, r_M'r_M = M'M - (Q'M)'(Q'M)
            c = self.qt @ m
            c_m = np.linalg.solve(m.T @ m - c.T @ c, m.T @ self.r_y - c.T @ self.qy)
            return self.r_y + self.qt.T @ (c @ c_m)
        r_m = m - self.b @ self.fac.solve(m)
        c_m = np.linalg.solve(r_m.T @ r_m, r_m.T @ self.r_y)
        return self.r_y + (m - r_m) @ c_m

    def explained(self, column: int, modulation_hz: float) -> float:
        """Power of record ``column`` that the modulation (and its harmonics) at
        ``modulation_hz`` [Hz] explains beyond the slow part and the orders:
        ``r_y' r_M (r_M' r_M)^-1 r_M' r_y`` (Frisch-Waugh-Lovell, as :meth:`at`)."""
        return self.explained_many([column], [modulation_hz])[0]

    def explained_many(self, columns, frequencies_hz) -> list[float]:
        """:meth:`explained` of record ``columns[i]`` at ``frequencies_hz[i]`` [Hz] for every
        i, in one compiled call on the orthonormal basis of B
        (:func:`torquemod.dsp.tonesearch.explained_power`); without that basis, with one
        least-squares solve on B for all the frequencies' columns together."""
        freqs = [float(f) for f in frequencies_hz]
        if self.qt is not None:  # one compiled call (dsp.tonesearch)
            return [float(v) for v in tonesearch.explained_power(
                self.qt, self.r_y, self.qy, self.fs_hz, freqs, columns, (1, *self.harmonics))]
        m = _modulation_columns_many(self.y.shape[0], self.fs_hz, freqs, self.harmonics)
        r_all = m - self.b @ self.fac.solve(m)
        k = m.shape[1] // len(freqs)
        out = []
        for i, col in enumerate(columns):
            r_m = np.ascontiguousarray(r_all[:, i * k:(i + 1) * k])
            b = r_m.T @ self.r_y[:, col]
            out.append(float(b @ np.linalg.solve(r_m.T @ r_m, b)))
        return out

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
        return self.refine_many([column], [peak_hz], tol_hz=tol_hz)[0]

    def refine_many(self, columns, peaks_hz, *, tol_hz: float = 1e-6) -> list[float]:
        """:meth:`refine` of record ``columns[i]`` from ``peaks_hz[i]`` [Hz] for every i,
        the searches advancing in step so that each step's explained powers of all records
        come from one :meth:`explained_many` call (the same numbers as one :meth:`refine`
        per record)."""
        peaks = [float(p) for p in peaks_hz]
        if self.qt is None and self.fac is None:
            return peaks
        duration = self.y.shape[0] / self.fs_hz
        if self.qt is not None:  # the steps of _refine_steps in one compiled call (the
            # same numbers)
            return tonesearch.refine_peaks(self.qt, self.r_y, self.qy, self.fs_hz, duration,
                                           columns, peaks, self._orders, tol_hz=tol_hz)
        return self._refine_steps(columns, peaks, duration, tol_hz)

    def _refine_steps(self, columns, peaks: list[float], duration: float, tol_hz: float
                      ) -> list[float]:
        """:meth:`refine_many`'s steps, one :meth:`explained_many` call each."""
        f = list(peaks)
        active = list(range(len(peaks)))
        for h in (0.05 / duration, 0.005 / duration, 0.0005 / duration):
            if not active:
                break
            e = self.explained_many([columns[i] for i in active for _ in range(3)],
                                    [f[i] + k * h for i in active for k in (-1.0, 0.0, 1.0)])
            still = []
            for j, i in enumerate(active):
                e_lo, e_0, e_hi = e[3 * j:3 * j + 3]
                curvature = e_lo - 2.0 * e_0 + e_hi
                if not curvature < 0:  # not near a maximum: keep the spectral peak's value
                    f[i] = peaks[i]
                    continue
                step = min(max(0.5 * h * (e_lo - e_hi) / curvature, -2.0 * h), 2.0 * h)
                f[i] += step
                if not abs(step) < tol_hz:
                    still.append(i)
            active = still
        return f
