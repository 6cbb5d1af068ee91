"""The torque steps of a simulated procedure as independent pieces of work.

A step is integrated from its start time ``t_i`` (settling, then the recorded revolutions).
Run one after the other, each step would start from the state the step before ended in, which
serialises the procedure. Here each step starts instead from the steady state of the DC torque
before it (:func:`torquemod.twins.vtrack.theory.operating_point`), so that all steps can run at
once:

* the drive line and the wheel: the steady state at the previous DC torque
  (:func:`~torquemod.twins.vtrack.rig.dynamics.initial_state`), on the speed reference as it wobbles
  at
  ``t_i`` (the state's speeds scaled by ``W_ref/W0``);
* the platform angle, which no restoring force pulls back (a neutral state: an offset would
  stay for the rest of the run and shift the sleeper and joint loads): from
  ``d(th_p + i_pi)/dt = W_ref(t, th_p)`` -- exact for the twin's PI loop
  (:mod:`torquemod.twins.vtrack.rig.dynamics`: ``th_p' = W_p``, ``i_pi' = W_ref - W_p``) --
  integrated on
  its own by RK4 (:func:`_reference_angle`), with ``i_pi`` at each step's steady value;
* the wheel angle (read only by the encoder model): the platform's advance times
  ``(1 + xi)*R_p/R_w`` at each step's steady creepage.

What is left of the difference to the state a sequential run reaches -- the modulation's
response, the ramp's transient, the integral state's share of the modulation -- decays during
the settling time (the slowest mode, the PI loop's ``Ki/Kp = 2 1/s``, by ``exp(-8)`` over the
default 4 s). Measured on the default experiment: the simulated phases change by less than
1e-6 deg against the sequential run (benchmarks/simulate.py's docstring).
A step whose previous DC torque has no steady state (beyond the creep curve's peak) starts
from the end of the step before, as in a sequential run.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numba
import numpy as np

from torquemod.twins.vtrack.params import MAX_LAMBDA_H, SimConfig, explicit_rate
from torquemod.twins.vtrack.rig.dynamics import N_STATES, OUT_COLUMNS, _wobble, initial_state
from torquemod.twins.vtrack.rig.lanes import integrate_lanes, lane_settings, stack_wobbles
from torquemod.twins.vtrack.rig.wobble import _band_sines, _wobble_banded
from torquemod.twins.vtrack.theory import operating_point

#: the settling's RK4 step, in recorded steps: on the 16-point default batch the simulated
#: phases stay as close to a run at 4 samples a step as the recorded step's own error with
#: the settling at 2 recorded steps (<= 2.8e-5 deg per step, 1.1e-4 per revolution, against
#: 3.2e-5 and 1.1e-4 settling at 1), not at 3 (4.7e-5 and 1.3e-4) or at 7 (6.1e-5, 1.6e-4)
SETTLE_STEPS = 2


def settle_samples_per_step(config: SimConfig) -> int:
    """Output samples per RK4 step while the step settles (its samples are not recorded):
    :data:`SETTLE_STEPS` recorded steps, fewer if that step would take ``lambda*h`` of the
    explicit part (:func:`~torquemod.twins.vtrack.params.explicit_rate`) beyond
    :data:`~torquemod.twins.vtrack.params.MAX_LAMBDA_H`, at least the recorded step. Default
    rig: 24 samples (``lambda*h = 0.28`` for the torsional mode; the platform's PI loop is
    taken exactly).

    Parameters
    ----------
    config : SimConfig
        The twin's configuration.

    Returns
    -------
    int
        Samples per RK4 step [-].
    """
    proc, fs = config.procedure, config.sensors.sample_rate_hz
    rec = max(1, proc.samples_per_step // proc.substeps)
    fit = int(MAX_LAMBDA_H * fs / explicit_rate(config.rig))
    return max(rec, min(SETTLE_STEPS * rec, fit))


#: RK4 step [s] of the reference angle: the wobble's lines lie below 1 Hz, so that the
#: method's error (~(w*h)^4/120) stays below 1e-10 of the angle's wobble
_ANGLE_STEP_S = 0.01


@numba.njit(cache=True)
def _reference_angle(t_ends, phi0, w0, ipi, wob):
    """``phi = th_p + i_pi`` [rad] at the times ``t_ends`` (ascending, from 0) for
    ``phi' = W0 + wobble(t, phi - i_pi)`` (:func:`~torquemod.twins.vtrack.rig.dynamics._wobble`),
    ``phi(0) = phi0``, ``i_pi = ipi[k]`` on the way to ``t_ends[k]``; classical RK4. The
    band rows' sines depend on time only: each step evaluates them at its middle and end
    (shared by stages 2 and 3, and by stage 4 with the next step's stage 1;
    :func:`~torquemod.twins.vtrack.rig.wobble._wobble_banded`), the same values as four
    evaluations of :func:`_wobble`."""
    out = np.empty(t_ends.size)
    phi, t = phi0, 0.0
    b0, bm, b1 = np.zeros(wob.shape[0]), np.zeros(wob.shape[0]), np.zeros(wob.shape[0])
    _band_sines(t, wob, b0)
    for k in range(t_ends.size):
        n = max(1, math.ceil((t_ends[k] - t) / _ANGLE_STEP_S))
        h = (t_ends[k] - t) / n
        q = ipi[k]
        for _ in range(n):
            _band_sines(t + 0.5 * h, wob, bm)
            _band_sines(t + h, wob, b1)
            k1 = w0 + _wobble_banded(phi - q, wob, b0)
            k2 = w0 + _wobble_banded(phi + 0.5 * h * k1 - q, wob, bm)
            k3 = w0 + _wobble_banded(phi + 0.5 * h * k2 - q, wob, bm)
            k4 = w0 + _wobble_banded(phi + h * k3 - q, wob, b1)
            phi += h / 6.0 * (k1 + 2.0 * (k2 + k3) + k4)
            t += h
            b0, b1 = b1, b0
        out[k] = phi
    return out


@dataclass(frozen=True)
class StepPlan:
    """One torque step of a simulated run.

    Attributes
    ----------
    index : int
        The step, from 1.
    dc_from_nm : float
        DC torque before the ramp [N*m].
    dc_nm : float
        DC torque after it [N*m].
    t0_s : float
        Start of the ramp [s].
    phase_rad : float
        The modulation generator's phase [rad].
    y0 : ndarray or None
        The start state; None: the end state of the step before.
    """

    index: int
    dc_from_nm: float
    dc_nm: float
    t0_s: float
    phase_rad: float
    y0: np.ndarray | None


def plan_steps(config: SimConfig, wobble: np.ndarray, phases: list[float],
               n_step_samples: int, first: Callable[[StepPlan], None] | None = None
               ) -> list[StepPlan]:
    """The steps of ``config``'s procedure, each ``n_step_samples`` long at the sample rate,
    with their start states (module docstring); ``phases`` [rad] per step. ``first`` is
    called with the first step's plan as soon as it is known (before the operating points
    and the reference angle of the others), so that a caller can start integrating it.

    Parameters
    ----------
    config : SimConfig
        The twin's configuration.
    wobble : ndarray
        The wobble rows.
    phases : list of float
        Generator phase per step [rad].
    n_step_samples : int
        Samples per step [-].
    first : callable or None
        Called with the first step's plan. Default None.

    Returns
    -------
    list of StepPlan
        The steps.
    """
    rig, proc = config.rig, config.procedure
    dt = 1.0 / config.sensors.sample_rate_hz
    torques = proc.dc_torques_nm
    op0 = operating_point(torques[0], rig)
    start = torques[0]
    if op0.slipped:
        op0, start = operating_point(0.0, rig), 0.0
    y1 = initial_state(rig, creepage=op0.creepage, dc_torque_nm=start, contact_fx_n=op0.fx_n)
    plan1 = StepPlan(1, start, torques[0], 0.0, phases[0], y1)
    if first is not None:
        first(plan1)
    # step starts as the sequential run accumulates them
    t_starts, t = [], 0.0
    for _ in torques:
        t_starts.append(t)
        t += n_step_samples * dt
    ops = [op0] + [operating_point(dc, rig) for dc in torques[:-1]]
    steady = [None if op.slipped else initial_state(rig, creepage=op.creepage,
                                                    dc_torque_nm=dc, contact_fx_n=op.fx_n)
              for op, dc in zip(ops, (start, *torques[:-1]), strict=True)]
    # i_pi on the way to each step start: steady at the DC torque of the step running then
    ipi = np.array([y1[6] if s is None else s[6] for s in steady[1:]] or [y1[6]])
    w0 = rig.platform_speed_rad_s
    phi = _reference_angle(np.asarray(t_starts[1:] or [0.0]), y1[4] + y1[6], w0, ipi,
                           np.ascontiguousarray(wobble, dtype=np.float64))
    plans = [plan1]
    th_w, th_prev = y1[3], y1[4]
    for i in range(1, len(torques)):
        y = steady[i]
        th_p = phi[i - 1] - (y1[6] if y is None else y[6])
        op = ops[i]
        th_w += (th_p - th_prev) * (1.0 + (0.0 if op.slipped else op.creepage)) \
            * rig.platform_radius_m / rig.wheel_radius_m
        th_prev = th_p
        if y is not None:
            y = y.copy()
            scale = 1.0 + _wobble(t_starts[i], th_p, wobble) / w0
            y[[1, 2, 5]] *= scale
            y[3], y[4] = th_w, th_p
        plans.append(StepPlan(i + 1, torques[i - 1], torques[i], t_starts[i], phases[i], y))
    return plans


@dataclass(frozen=True)
class StepJob:
    """One step to integrate (:func:`integrate_steps`).

    Attributes
    ----------
    config : SimConfig
        The twin's configuration.
    params : ndarray
        Its packed parameters
        (:func:`~torquemod.twins.vtrack.rig.dynamics.pack_parameters`).
    wobble : ndarray
        The run's wobble table.
    plan : StepPlan
        The step.
    n_samples : int
        Samples to integrate [-].
    start : ndarray or None
        Start state when the plan has none. Default None.
    n_quiet : int
        Settling samples at the start, never recorded [-]. Default 0.
    """

    config: SimConfig
    params: np.ndarray
    wobble: np.ndarray
    plan: StepPlan
    n_samples: int
    start: np.ndarray | None = None
    n_quiet: int = 0


def steps_buffer_shape(jobs: list[StepJob]) -> tuple[int, int, int]:
    """Shape of the samples of :func:`integrate_steps` for ``jobs``.

    Parameters
    ----------
    jobs : list of StepJob
        The steps.

    Returns
    -------
    tuple of int
        (steps, samples of the longest, columns).
    """
    return len(jobs), max((j.n_samples for j in jobs), default=0), len(OUT_COLUMNS)


def _job_args(job: StepJob, phase: int) -> tuple:
    """Lane settings (:func:`~torquemod.twins.vtrack.rig.lanes.lane_settings`) of ``job``'s
    settling at the longest stable step (``phase`` 0; None when it has none) or of the rest
    (``phase`` 1), with that phase's sample count and first row."""
    config, plan = job.config, job.plan
    proc, mod = config.procedure, config.modulation
    dt = 1.0 / config.sensors.sample_rate_hz
    r = settle_samples_per_step(config)
    n_c = (min(job.n_quiet, job.n_samples) // r
           if r * proc.substeps >= proc.samples_per_step else 0)
    rest = (plan.dc_from_nm, plan.dc_nm, plan.t0_s, proc.ramp_s, mod.amplitude_nm,
            2.0 * np.pi * mod.actual_frequency_hz, plan.phase_rad, plan.t0_s,
            proc.slip_creepage)
    if phase == 0:
        return (lane_settings(plan.t0_s, n_c, r * dt, 1, *rest, 1), n_c, r) if n_c else None
    i0 = n_c * r
    return lane_settings(plan.t0_s + i0 * dt, job.n_samples - i0, dt, proc.substeps, *rest,
                         proc.samples_per_step, i0), job.n_samples - i0, i0


def integrate_steps(jobs: list[StepJob], buffer: np.ndarray | None = None
                    ) -> list[tuple[np.ndarray, int, bool, np.ndarray]]:
    """Integrate the steps ``jobs`` side by side, one lane each
    (:func:`~torquemod.twins.vtrack.rig.lanes.integrate_lanes`): per job what
    :func:`integrate_step` returns for it, number for number. The settling phases run
    together, then the recorded phases of the steps that did not slip in theirs.

    The samples are written into ``buffer`` when it has the shape they need (``(jobs,
    longest, columns)``, see :func:`steps_buffer`), else into a new array: a caller that
    runs group after group reuses one array instead of mapping fresh memory for each (an
    array that large is given back to the system when freed, and its pages are faulted in
    anew).

    Parameters
    ----------
    jobs : list of StepJob
        The steps, one lane each.
    buffer : ndarray or None
        Where to write the samples, if of the shape :func:`steps_buffer_shape`. Default
        None.

    Returns
    -------
    list of tuple
        Per job ``(out, n_written, slipped, end state)`` as :func:`integrate_step`.
    """
    nl = len(jobs)
    y = np.array([j.plan.y0 if j.plan.y0 is not None else j.start for j in jobs],
                 dtype=np.float64).reshape(nl, N_STATES)
    params = np.array([j.params for j in jobs], dtype=np.float64)
    wob, nw = stack_wobbles([j.wobble for j in jobs])
    shape = steps_buffer_shape(jobs)
    out = buffer if buffer is not None and buffer.shape == shape else np.empty(shape)
    done = [None] * nl
    coarse = [(k, _job_args(j, 0)) for k, j in enumerate(jobs)]
    coarse = [(k, a) for k, a in coarse if a is not None]
    if coarse:
        idx = [k for k, _ in coarse]
        settings, n_c, r = zip(*(a for _, a in coarse), strict=True)
        sf, si = (np.array(a) for a in zip(*settings, strict=True))
        yc = y[idx]
        scratch = np.empty((len(idx), max(n_c), len(OUT_COLUMNS)))
        res = integrate_lanes(yc, sf, si, params[idx], wob[idx], nw[idx], scratch)
        y[idx] = yc
        for q, k in enumerate(idx):
            if res[q, 1]:
                done[k] = (out[k, :jobs[k].n_samples], int(res[q, 0] - 1) * r[q] + 1, True,
                           y[k])
    idx = [k for k in range(nl) if done[k] is None]
    if idx:
        fine = [_job_args(jobs[k], 1) for k in idx]
        sf, si = (np.array(a) for a in zip(*(f[0] for f in fine), strict=True))
        yf = y[idx]
        sub = out if len(idx) == nl else np.empty((len(idx), out.shape[1], out.shape[2]))
        res = integrate_lanes(yf, sf, si, params[idx], wob[idx], nw[idx], sub)
        for q, k in enumerate(idx):
            if sub is not out:
                out[k] = sub[q]
            done[k] = (out[k, :jobs[k].n_samples], fine[q][2] + int(res[q, 0]),
                       bool(res[q, 1]), yf[q].copy())
    return done


def integrate_step(config: SimConfig, params: np.ndarray, wobble: np.ndarray, plan: StepPlan,
                   n_samples: int, start: np.ndarray | None = None, n_quiet: int = 0
                   ) -> tuple[np.ndarray, int, bool, np.ndarray]:
    """Integrate the step ``plan`` over ``n_samples`` samples from its start state (or from
    ``start`` when the plan has none): ``(out, n_written, slipped, end state)`` with ``out``
    the samples of :data:`~torquemod.twins.vtrack.rig.dynamics.OUT_COLUMNS`
    (:func:`~torquemod.twins.vtrack.rig.lanes.integrate`; ``params`` from
    :func:`~torquemod.twins.vtrack.rig.dynamics.pack_parameters`).

    The first ``n_quiet`` samples (the settling, never recorded) are integrated at the
    longest stable step (:func:`settle_samples_per_step`, one RK4 step per coarse sample, no
    samples inside the steps): their rows of ``out`` are left unset except the last whole
    coarse block's remainder. A slip among them is reported at the coarse sample's index
    (``n_written`` to within a coarse step). :func:`integrate_steps` with one step.

    Parameters
    ----------
    config : SimConfig
        The twin's configuration.
    params : ndarray
        The parameter vector.
    wobble : ndarray
        The wobble rows.
    plan : StepPlan
        The step.
    n_samples : int
        Samples [-].
    start : ndarray or None
        Start state when the plan has none. Default None.
    n_quiet : int
        Settling samples at the start [-]. Default 0.

    Returns
    -------
    out : ndarray
        The samples.
    n_written : int
        Samples written.
    slipped : bool
        The wheel slipped.
    end : ndarray
        The end state.
    """
    return integrate_steps([StepJob(config, params, wobble, plan, n_samples, start,
                                    n_quiet)])[0]
