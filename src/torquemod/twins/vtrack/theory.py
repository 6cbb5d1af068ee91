"""Small-signal theory of torque modulation: phase lag <-> creep coefficient.

Sign convention of the project: ``phase_deg > 0`` when the measured wheel angular velocity
lags the measured torque.

Rigid wheel (the V-Track paper's Eq. (1) with its constant). Linearising the
wheel ``J*w' = T - R*F_x`` with ``F_x = N*k*xi_x`` and ``xi_x = (w*R - V)/V`` gives::

    dw/dT = 1 / (j*Omega*J + R^2*N*k/V)   =>   tan(phi) = Omega*J*V / (R^2*N*k)

with ``Omega = 2*pi*f_mod`` and ``k = dCoA/dxi_x`` the creep coefficient.

Drive line (this module's :func:`drive_line_response`): motor inertia -- torque shaft
(stiffness, damping) -- torque sensor -- wheel -- contact -- platform on its PI speed
controller. The torque sensor sits in series with the shaft and its encoder turns with the
wheel, so the measured pair (shaft torque, wheel speed) brackets exactly the inertia
*downstream of the sensor* (``RigParams.wheel_inertia_kg_m2``): the motor side and the shaft
change amplitudes but cancel from the phase. What remains beyond the rigid formula is the
platform: the traction reaction ``F_x*R_p`` makes the platform speed, and hence the rolling
speed, respond a little, which is included here exactly as in the simulator.

Large signal (:func:`large_signal_phase_deg`): near saturation the 8 N*m modulation swings
the creepage over the curved part of the creep curve (and at step 1 through zero, where the
combined-creepage Polach force bends sharply), so the measured phase departs from the
small-signal value by up to ~1.8 deg on the default rig. The periodic steady state of the
nonlinear model is computed by harmonic balance and its first harmonics give that phase.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, replace

import numpy as np
from scipy.optimize import brentq, minimize_scalar

from torquemod.analysis.contact.polach import creep_force
from torquemod.errors import InputError
from torquemod.twins.vtrack.params import RigParams
from torquemod.twins.vtrack.smallsignal import (
    drive_line_response,
    predicted_phase_deg,
    response_phase_deg,
)
from torquemod.twins.vtrack.theory_kernels import (
    _dense_solve,  # noqa: F401 - its old home
    newton_periodic,
    orbit_forces,
    pack_constants,
)

# --------------------------------------------------------------------------------------------
# Steady state of the Polach contact
# --------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class OperatingPoint:
    """Steady rolling under a DC torque.

    Attributes
    ----------
    dc_torque_nm : float
        The DC torque [N*m].
    creepage : float
        Longitudinal creepage xi_x [-].
    coa : float
        sqrt(Fx^2 + Fy^2)/Fz [-].
    creep_coefficient : float
        d(Fx/Fz)/dxi_x [-] (what the phase responds to; equals dCoA/dxi_x without lateral
        creepage).
    dcoa_dxi : float
        dCoA/dxi_x [-].
    fx_n : float
        Longitudinal force [N].
    fy_n : float
        Lateral force [N].
    slipped : bool
        The torque exceeds what the creep curve can carry (the other fields are then NaN).
    """

    dc_torque_nm: float
    creepage: float
    coa: float
    creep_coefficient: float
    dcoa_dxi: float
    fx_n: float
    fy_n: float
    slipped: bool


def _fx(xi_x, params: RigParams):
    c = params.contact
    return creep_force(xi_x, c.lateral_creepage, normal_load_n=params.normal_load_n,
                       speed_m_s=params.speed_m_s, **c.polach_kwargs())


def creep_curve_peak(params: RigParams, *, max_creepage: float = 0.5) -> tuple[float, float]:
    """The largest DC torque the wheel can carry in steady rolling, and its creepage.

    The maximum of ``R_w*F_x(xi_x)`` (beyond it the wheel slips). Remembered per parameter set
    when ``params`` is a (frozen) :class:`RigParams`: every :func:`operating_point` needs it
    (~1 ms); other objects are computed every time.

    Parameters
    ----------
    params : RigParams
        The rig.
    max_creepage : float
        Upper end of the creepage searched [-]. Default 0.5.

    Returns
    -------
    creepage : float
        At the peak [-].
    torque_nm : float
        The peak torque [N*m].
    """
    if type(params) is RigParams:
        return _creep_curve_peak_memo(params, float(max_creepage))
    return _creep_curve_peak(params, max_creepage)


def _creep_curve_peak(params: RigParams, max_creepage: float) -> tuple[float, float]:
    grid = np.geomspace(1e-7, max_creepage, 4000)
    fx = _fx(grid, params)[0]
    i = int(np.argmax(fx))
    lo, hi = grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)]
    res = minimize_scalar(lambda x: -float(_fx(x, params)[0]), bounds=(lo, hi),
                          method="bounded", options={"xatol": 1e-12})
    xi = float(res.x)
    return xi, float(_fx(xi, params)[0]) * params.wheel_radius_m


_creep_curve_peak_memo = functools.lru_cache(maxsize=256)(_creep_curve_peak)


def operating_point(dc_torque_nm: float, params: RigParams) -> OperatingPoint:
    """Solve ``T_dc = R_w*F_x(xi_x, xi_y)`` for xi_x on the rising branch (scipy brentq) and
    return the steady-state creepage, CoA and creep coefficients (central differences).
    Remembered per (DC torque, parameter set) when ``params`` is a (frozen)
    :class:`RigParams`: a twin run asks for each step's point three times (its plan, the
    step's truth and the large-signal theory), ~0.7 ms each with the GIL held.

    Parameters
    ----------
    dc_torque_nm : float
        The DC torque [N*m].
    params : RigParams
        The rig.

    Returns
    -------
    OperatingPoint
        ``slipped`` when the torque exceeds the creep curve's peak.
    """
    if type(params) is RigParams:
        return _operating_point_memo(float(dc_torque_nm), params)
    return _operating_point(dc_torque_nm, params)


def _operating_point(dc_torque_nm: float, params: RigParams) -> OperatingPoint:
    xi_peak, t_peak = creep_curve_peak(params)
    rw, n = params.wheel_radius_m, params.normal_load_n
    if dc_torque_nm >= t_peak:
        nan = float("nan")
        return OperatingPoint(dc_torque_nm, nan, nan, nan, nan, nan, nan, True)
    lo = -xi_peak
    xi = brentq(lambda x: float(_fx(x, params)[0]) * rw - dc_torque_nm, lo, xi_peak,
                xtol=1e-15, rtol=1e-13, maxiter=500)
    h = max(1e-9, 1e-4 * abs(xi))
    fxp, fyp = _fx(xi + h, params)
    fxm, fym = _fx(xi - h, params)
    fx, fy = _fx(xi, params)
    k = float(fxp - fxm) / (2 * h) / n
    coa_p, coa_m = np.hypot(fxp, fyp) / n, np.hypot(fxm, fym) / n
    return OperatingPoint(dc_torque_nm=float(dc_torque_nm), creepage=float(xi),
                          coa=float(np.hypot(fx, fy) / n), creep_coefficient=k,
                          dcoa_dxi=float(coa_p - coa_m) / (2 * h), fx_n=float(fx),
                          fy_n=float(fy), slipped=False)


_operating_point_memo = functools.lru_cache(maxsize=4096)(_operating_point)


# --------------------------------------------------------------------------------------------
# Large-signal prediction: periodic steady state under the full modulation amplitude
# --------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class LargeSignalResult:
    """Periodic steady state of the wheel and contact (and platform) under ``T_dc + A*sin``.

    Attributes
    ----------
    dc_torque_nm : float
        T_dc [N*m].
    amplitude_nm : float
        A [N*m].
    frequency_hz : float
        Modulation frequency [Hz].
    phase_deg : float
        First-harmonic phase of the wheel speed behind the measured (shaft) torque [deg]
        (positive = lag).
    speed_amplitude_rad_s : float
        Amplitude of the wheel speed's first harmonic [rad/s].
    torque_amplitude_nm : float
        Amplitude of the measured torque's first harmonic [N*m] (= ``amplitude_nm`` when
        driven by the shaft torque).
    mean_creepage : float
        Time average of xi_x over a period [-].
    creepage_min, creepage_max : float
        Its extremes [-].
    mean_creep_coefficient : float
        Period mean of d(F_x/N)/dxi_x along the orbit [-] (the wheel's mean damping: the orbit
        is unstable when it is not positive).
    steady_creepage : float
        xi_x under the DC torque alone [-].
    small_signal_phase_deg : float
        :func:`predicted_phase_deg` at the DC operating point [deg].
    iterations : int
        Newton iterations taken.
    n_samples : int
        Collocation points per period used.
    slipped : bool
        The DC torque exceeds the creep-curve peak or no periodic solution was found (the
        wheel runs away; the other fields are then NaN).
    """

    dc_torque_nm: float
    amplitude_nm: float
    frequency_hz: float
    phase_deg: float
    speed_amplitude_rad_s: float
    torque_amplitude_nm: float
    mean_creepage: float
    creepage_min: float
    creepage_max: float
    mean_creep_coefficient: float
    steady_creepage: float
    small_signal_phase_deg: float
    iterations: int
    n_samples: int
    slipped: bool


@functools.lru_cache(maxsize=8)
def _eye_spectrum(n: int) -> np.ndarray:
    """``rfft`` of the ``n x n`` identity along its columns (read-only; remembered per ``n``:
    every :func:`_circulant` of a collocation size starts from it)."""
    out = np.fft.rfft(np.eye(n), axis=0)
    out.flags.writeable = False
    return out


def _circulant(symbol: np.ndarray, n: int) -> np.ndarray:
    """Real ``n x n`` matrix of the periodic linear operator whose frequency response at
    harmonic k = 0..n/2 is ``symbol[k]`` (the Nyquist bin is set to zero)."""
    h = np.array(symbol, dtype=complex)
    h[-1] = 0.0
    return np.fft.irfft(h[:, None] * _eye_spectrum(n), n=n, axis=0)


def _refine(x: np.ndarray, n: int, platform: bool) -> np.ndarray:
    """A collocation solution on ``n`` points per period (``u``, then ``w`` with the
    platform) resampled to ``2n`` points by trigonometric interpolation (its spectrum padded
    with zeros; the Nyquist bin, which collocation leaves unresolved, dropped)."""
    parts = [x[:n], x[n:]] if platform else [x]
    out = []
    for v in parts:
        spec = np.fft.rfft(v)
        spec[-1] = 0.0
        out.append(np.fft.irfft(spec, n=2 * n) * 2.0)
    return np.concatenate(out)


def _operators(p: RigParams, f: float, n: int, drive: str, platform: bool) -> tuple:
    """The collocation's operators on ``n`` points per period at ``f`` [Hz]: the unit drive
    at the collocation instants, ``L`` (``J_w d/dt``, plus ``G2`` when the motor drives),
    ``P`` (``R_p H_p``, the platform loop), ``P L`` and ``G2`` (None when the shaft torque
    drives) -- circulant matrices built by FFT (:func:`_circulant`). They depend on the rig,
    not on the DC torque: remembered per argument set when ``p`` is a (frozen)
    :class:`RigParams` (every step of a run shares them; never written to)."""
    if type(p) is RigParams:
        return _operators_memo(p, f, n, drive, platform)
    return _build_operators(p, f, n, drive, platform)


def _build_operators(p, f, n, drive, platform) -> tuple:
    """:func:`_operators`, computed."""
    om = 2.0 * np.pi * f
    s = 1j * om * np.arange(n // 2 + 1)
    t = np.arange(n) / (n * f)
    rp = p.platform_radius_m
    lin_w = p.wheel_inertia_kg_m2 * _circulant(s, n)  # J_w d/dt
    lin_sym = p.wheel_inertia_kg_m2 * s  # its frequency response
    with np.errstate(divide="ignore", invalid="ignore"):
        z_s = p.shaft_stiffness_nm_rad / s + p.shaft_damping_nm_s_rad
        g1 = z_s / (p.drive_inertia_kg_m2 * s + z_s)
        g2 = p.drive_inertia_kg_m2 * s * z_s / (p.drive_inertia_kg_m2 * s + z_s)
        hp = 1.0 / (p.platform_inertia_kg_m2 * s + p.platform_kp_nm_s_rad
                    + p.platform_ki_nm_rad / s)
    if drive == "shaft":
        sine = np.sin(om * t)
        g2_op = None
    else:  # T_sh = G1 T_m - G2 w; G1(0) = 1, G2(0) = 0, T_m holds DC and harmonic 1 only
        sine = np.imag(g1[1] * np.exp(1j * om * t))
        g2[0] = 0.0
        g2_op = _circulant(g2, n)
        lin_w = lin_w + g2_op
        lin_sym = lin_sym + g2
    if platform:
        hp[0] = 0.0  # integral action: the platform's mean speed is the set speed
        p_mat = np.ascontiguousarray(rp * _circulant(hp, n))
        pl_mat = np.ascontiguousarray(_circulant(rp * hp * lin_sym, n))  # P L
    else:
        p_mat = pl_mat = np.zeros((0, 0))
    return np.ascontiguousarray(sine), np.ascontiguousarray(lin_w), p_mat, pl_mat, g2_op


_operators_memo = functools.lru_cache(maxsize=64)(_build_operators)


def _periodic_state(dc_torque_nm, p: RigParams, op: OperatingPoint, f: float, amplitude: float,
                    drive: str, platform: bool, n: int, rtol: float, max_iter: int,
                    start: np.ndarray | None = None, response: tuple | None = None):
    """Collocation solve of :func:`large_signal_phase_deg` on ``n`` points per period,
    from ``start`` (the unknowns on ``n/2`` points, :func:`_refine`) when given, else from
    the small-signal response (``response``: :func:`drive_line_response` at the operating
    point when already known).

    Returns ``(torque, u, xi, k_mean, iterations, x)`` -- measured torque [N*m], wheel-speed
    deviation from the steady state [rad/s] and creepage [-] at the collocation instants, the
    period mean of d(F_x/N)/dxi_x [-], the unknowns -- or None when Newton's method (with
    amplitude continuation) finds no periodic solution."""
    om = 2.0 * np.pi * f
    t = np.arange(n) / (n * f)
    rw, rp, n0 = p.wheel_radius_m, p.platform_radius_m, p.normal_load_n
    wref = p.platform_speed_rad_s
    v0 = wref * rp
    kw = p.contact.polach_kwargs()
    xiy = p.contact.lateral_creepage
    sine_c, lin_c, p_mat, pl_mat, g2_op = _operators(p, f, n, drive, platform)
    consts = pack_constants(rw, rp, n0, wref, v0, float(op.creepage), xiy, kw)

    def newton(x, amp):  # compiled, without the GIL (theory_kernels.py)
        return newton_periodic(x, float(amp), float(dc_torque_nm), sine_c, lin_c, p_mat,
                               pl_mat, platform, n, consts, float(rtol), int(max_iter))

    # start: the steady state plus the small-signal response of the wheel speed
    if start is not None:  # the solution on half the points, interpolated
        x = _refine(start, n // 2, platform)
    else:
        h_t, h_w = response if response is not None else drive_line_response(
            op.creep_coefficient, p, f, creepage=op.creepage)
        h1 = h_w / h_t if drive == "shaft" else h_w
        x = np.zeros(2 * n if platform else n)
        x[:n] = amplitude * np.imag(h1 * np.exp(1j * om * t))
    x, iters, ok = newton(x, amplitude)
    if not ok:  # amplitude continuation from the steady state
        x, iters = np.zeros_like(x), 0
        for frac in np.linspace(0.125, 1.0, 8):
            x, it, ok = newton(x, frac * amplitude)
            iters += it
            if not ok:
                return None
    u = x[:n]
    hu = 1e-7 * (1.0 + np.abs(u).max())
    xi, f_plus, f_minus = orbit_forces(x, platform, n, consts, hu)
    k_mean = float(np.mean(f_plus - f_minus)) / (2.0 * hu) \
        * (wref * rp) / (rw * n0)  # dF/du = dF/dxi * R_w/V; V varies by < 1e-5 relative
    torque = dc_torque_nm + amplitude * sine_c
    if g2_op is not None:
        torque = torque - g2_op @ u
    return torque, u, xi, k_mean, iters, x


def large_signal_phase_deg(dc_torque_nm: float, params: RigParams, frequency_hz: float,
                           amplitude_nm: float, *, drive: str = "shaft", platform: bool = True,
                           n_samples: int = 64, rtol: float = 1e-10,
                           max_iter: int = 50) -> LargeSignalResult:
    """Large-signal phase: first-harmonic phase [deg] of the wheel speed behind the measured
    torque in the *periodic steady state* of the nonlinear wheel-contact model, for a
    modulation of ``amplitude_nm`` [N*m] at ``frequency_hz`` [Hz] on ``dc_torque_nm``.

    Model: the equations of :mod:`torquemod.twins.vtrack.rig.dynamics` with the normal load constant
    at
    ``params.normal_load_n`` and no disturbances, Polach (2005) contact with the rig's
    constant lateral creepage ``params.contact.lateral_creepage``::

        J_w w' = T_sh(t) - R_w*F_x(xi_x, xi_y, N0, V),   xi_x = (w*R_w - V)/V,  V = W_p*R_p
        (J_p s + K_p + K_i/s) dW_p = R_p dF_x          (platform speed loop, ``platform``)

    ``drive = "shaft"`` (default): ``T_sh = T_dc + A*sin(Omega*t)`` is the measured torque
    itself, ``A`` its amplitude. With the sensor in the shaft and its encoder on the wheel the
    wheel equation is closed given T_sh, so the drive line upstream drops out (exactly so for
    the small-signal phase, :func:`drive_line_response`). At large signal two things remain:
    the measured amplitude is smaller than the motor's near saturation (``|h_torque|*A``:
    6.85 N*m for 8 N*m at the default step 6) and the measured torque carries the harmonics
    the wheel sends back (<= 0.11 deg on the default rig).
    ``drive = "motor"``: ``A`` is the motor-torque amplitude (the simulator's
    ``modulation.amplitude_nm``) and the motor inertia and torque shaft are included:
    ``T_sh = G1(s) T_m - G2(s) w``, ``G1 = Z_s/(J_m s + Z_s)``, ``G2 = J_m s Z_s/(J_m s + Z_s)``,
    ``Z_s = k_t/s + c_t``; the phase is then taken against the first harmonic of that T_sh.
    ``platform = False`` holds the platform at its set speed (the small-signal value is then
    that of a stiff platform); the platform loop shifts the phase by 0.03-0.12 deg here.

    Method: harmonic balance by trigonometric collocation (M. Urabe, Arch. Ration. Mech.
    Anal. 20 (1965) 120-152) in the alternating frequency/time form of T. M. Cameron and
    J. H. Griffin, J. Appl. Mech. 56 (1989) 149-154. Unknowns are the wheel and platform
    speeds at ``n_samples`` equispaced instants of one period; d/dt and the linear transfer
    functions act as circulant matrices built by FFT, the Polach force pointwise in time.
    Newton-Raphson (dense Jacobian, finite differences of the contact force, each step
    solved through the Jacobian's ``n x n`` Schur complement since the platform equation is
    linear in the force, backtracking on the residual; compiled without the GIL,
    :func:`torquemod.twins.vtrack.theory_kernels.newton_periodic`)
    from the steady state plus the small-signal response, with amplitude continuation as a
    fallback; ``rtol`` is the last Newton step relative to the speed swing.
    The phase and amplitudes are DFT bin 1 of the converged signals. If the wheel speed's
    harmonics in the top eighth of the resolved band (3n/8 to n/2) exceed 1e-6 of the first,
    ``n_samples`` is doubled (up to 1024), Newton starting from the solution on half the
    points interpolated (two or three iterations instead of about four; the converged
    phase moves by < 1e-13 deg against a start from the small-signal response).
    On the default rig at 8 N*m the default 64 points
    (128 at step 1, where the creepage swings through zero and resolves most slowly) agree
    with 1024 to 1e-9 deg and with the simulator to 1e-3 deg (``drive = "motor"``). Cost
    0.5-3 ms per call, plus about 0.2 s once per process to load the compiled solver.
    Remembered per argument set when ``params`` is a (frozen) :class:`RigParams`: a sweep
    asks again for the points its seeds repeat, a run written to files for the theory its
    truth already holds.

    Raises InputError for an unknown ``drive``, ``frequency_hz <= 0``, ``amplitude_nm <= 0``
    or an odd/too small ``n_samples``. A DC torque above the creep-curve peak, or no periodic
    solution (the wheel runs away), gives ``slipped = True`` with NaN results; an orbit whose
    mean creep coefficient is not positive (unstable) is returned with ``slipped = True``.
    Near the peak the periodic state is reached slowly (the wheel's time constant is
    ``J_w*V/(R_w^2*N*k_mean)``): a simulation must settle for several of those.

    Parameters
    ----------
    dc_torque_nm : float
        T_dc [N*m].
    params : RigParams
        The rig.
    frequency_hz : float
        Modulation frequency [Hz].
    amplitude_nm : float
        A [N*m].
    drive : {"shaft", "motor"}
        What A drives. Default "shaft".
    platform : bool
        Include the platform's speed loop. Default True.
    n_samples : int
        Collocation points per period, even and >= 16 [-]. Default 64.
    rtol : float
        Convergence tolerance, relative to the speed swing [-]. Default 1e-10.
    max_iter : int
        Largest number of Newton iterations [-]. Default 50.

    Returns
    -------
    LargeSignalResult
        The periodic state.

    Raises
    ------
    InputError
        An unknown ``drive``, ``frequency_hz <= 0``, ``amplitude_nm <= 0`` or an odd/too
        small ``n_samples``.

    References
    ----------
    .. [1] O. Polach, "Creep forces in simulations of traction vehicles running on adhesion
       limit", Wear 258 (2005) 992-1000.
    .. [2] M. Urabe, "Galerkin's procedure for nonlinear periodic systems", Arch. Ration. Mech.
       Anal. 20 (1965) 120-152.
    .. [3] T.M. Cameron and J.H. Griffin, "An alternating frequency/time domain method for
       calculating the steady-state response of nonlinear dynamic systems", J. Appl. Mech.
       56 (1989) 149-154.
    """
    if type(params) is RigParams:
        return _large_signal_memo(float(dc_torque_nm), params, float(frequency_hz),
                                  float(amplitude_nm), drive, bool(platform), int(n_samples),
                                  float(rtol), int(max_iter))
    return _large_signal(dc_torque_nm, params, frequency_hz, amplitude_nm, drive, platform,
                         n_samples, rtol, max_iter)


def _large_signal(dc_torque_nm, params, frequency_hz, amplitude_nm, drive, platform,
                  n_samples, rtol, max_iter) -> LargeSignalResult:
    """:func:`large_signal_phase_deg` (its arguments in order)."""
    if drive not in ("shaft", "motor"):
        raise InputError(f"drive must be 'shaft' or 'motor', got {drive!r}")
    if not (np.isfinite(frequency_hz) and frequency_hz > 0):
        raise InputError(f"modulation frequency {frequency_hz} Hz must be > 0")
    if not (np.isfinite(amplitude_nm) and amplitude_nm > 0):
        raise InputError(f"modulation amplitude {amplitude_nm} N*m must be > 0",
                         hint="for a vanishing amplitude use predicted_phase_deg")
    if n_samples < 16 or n_samples % 2:
        raise InputError(f"n_samples must be even and >= 16, got {n_samples}")
    f, amp, dc = float(frequency_hz), float(amplitude_nm), float(dc_torque_nm)
    op = operating_point(dc, params)
    nan = float("nan")
    if op.slipped:
        return LargeSignalResult(dc, amp, f, nan, nan, nan, nan, nan, nan, nan, nan, nan, 0,
                                 n_samples, True)
    response = None
    if platform:  # the start's small-signal response gives the small-signal phase too
        response = drive_line_response(op.creep_coefficient, params, f, creepage=op.creepage)
        small = float(response_phase_deg(*response))
    else:
        small = float(predicted_phase_deg(op.creep_coefficient, _stiff_platform(params), f,
                                          creepage=op.creepage))
    n = n_samples
    start = None
    while True:
        sol = _periodic_state(dc, params, op, f, amp, drive, platform, n, rtol, max_iter,
                              start, response)
        if sol is None:
            return LargeSignalResult(dc, amp, f, nan, nan, nan, nan, nan, nan, nan,
                                     float(op.creepage), small, 0, n, True)
        torque, u, xi, k_mean, iters, start = sol
        spec = np.abs(np.fft.rfft(u))
        if spec[3 * n // 8:n // 2].max() <= 1e-6 * spec[1] or n >= 1024:
            break
        n *= 2
    t1, w1 = np.fft.rfft(torque)[1], np.fft.rfft(u)[1]
    return LargeSignalResult(
        dc_torque_nm=dc, amplitude_nm=amp, frequency_hz=f,
        phase_deg=float(np.degrees(np.angle(t1 / w1))),
        speed_amplitude_rad_s=float(2.0 * abs(w1) / n),
        torque_amplitude_nm=float(2.0 * abs(t1) / n), mean_creepage=float(xi.mean()),
        creepage_min=float(xi.min()), creepage_max=float(xi.max()),
        mean_creep_coefficient=k_mean, steady_creepage=float(op.creepage),
        small_signal_phase_deg=small, iterations=iters, n_samples=n, slipped=not k_mean > 0)


_large_signal_memo = functools.lru_cache(maxsize=4096)(_large_signal)


def _stiff_platform(params: RigParams) -> RigParams:
    """``params`` with the platform held at its set speed (an infinitely stiff speed loop)."""
    return replace(params, platform_kp_nm_s_rad=1e15, platform_ki_nm_rad=0.0)
