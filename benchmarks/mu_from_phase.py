"""The available adhesion from the phase alone on a rig simulated apart from torquemod: the
rig of ``tests/independent_rig.py`` (motor, elastic shaft, wheel on a platform, Polach's
law with constant friction; scipy's DOP853; it imports nothing of torquemod), without force
channels and, in the main case, without the inertia (C not given).

Each case: six torque steps at V-Track's proportions (0.0035, 0.35, 0.68, 0.84, 0.92, 1.0)
of ``u_max`` times the available adhesion (the curve's interior peak when kA < kS, else its
friction coefficient, the supremum it rises to) with the paper's 8 N*m modulation at 2 Hz;
per step the phase of the wheel speed behind the shaft torque by the reference definition of
that module (least-squares sinusoids over 8 periods after a 6 s run-in), the creepage swing
from the wheel speed's amplitude (``|W|*R/V``), the CoA from the DC torque (``T/(R*N)``).
Each simulated case is fitted once without noise and ``--draws`` times with Gaussian phase
noise of ``--noise-deg`` per step (stated as its standard error), with C not given, C
measured from the amplitudes (``sin(phi)*|T|/|w|*V/(R^2*N)`` per step, the median, its
standard error propagated: :func:`torquemod.analysis.phasefit.constant_from_amplitudes`;
the amplitude ratio drawn with a relative error equal to the phase noise in radians) and C
given (the truth). Also printed: the inertia measured from the noise-free amplitudes against
the rig's.
Prints per case the truth, the share determined, the median and worst error where determined
and the coverage of the stated range (the interval when closed, else the lower bound).

    python benchmarks/mu_from_phase.py [--draws 10] [--noise-deg 0.3] [--depths 0.95 0.9 0.86]
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
import independent_rig as ir
from torquemod.analysis.friction import fit_available_adhesion_from_phase
from torquemod.analysis.phasefit import constant_from_amplitudes

FRACTIONS = np.array([0.0035, 0.35, 0.68, 0.84, 0.92, 1.0])
#: (name, kA, kS): Polach's dry and wet sets (kA/kS 2.5 and 3), kA = kS (the independent
#: rig's default) and kA < kS (the curve peaks inside)
SHAPES = (("dry", 1.0, 0.4), ("wet", 0.3, 0.1), ("even", 0.2, 0.2), ("kA<kS", 0.15, 0.3))
F_MOD = 2.0


def available_adhesion(rig: ir.OrbitRig) -> float:
    """The curve's maximum CoA: the interior peak when there is one inside the search range
    of :func:`independent_rig.peak`, else the friction coefficient (the supremum)."""
    xi_pk, t_pk = ir.peak(rig)
    if xi_pk < 0.199:
        return t_pk / (rig.wheel_radius_m * rig.normal_load_n)
    return rig.mu


def simulate_case(rig: ir.OrbitRig, u_max: float) -> dict | None:
    """CoA, phase [deg] and creepage swing of the six steps, and the truth; None when the
    top step lies beyond the curve at the creepage 0.2 (the rig's search range)."""
    p = available_adhesion(rig)
    r, n = rig.wheel_radius_m, rig.normal_load_n
    if u_max * p * r * n >= ir.peak(rig)[1]:
        return None
    coa, phase, swing, t_amp, w_amp = [], [], [], [], []
    for frac in FRACTIONS:
        run = ir.Run(rig, dc_torque_nm=frac * u_max * p * r * n, modulation_hz=F_MOD,
                     run_in_s=6.0, duration_s=4.0)
        on = ir.simulate(run)
        zero = {k: np.zeros_like(v) for k, v in on.items()}
        phase.append(ir.record_phase_deg(on, zero, run.fs_hz, F_MOD))
        slow = ir.slow_space(on["torque_nm"].size, run.fs_hz, 0.4 * F_MOD)
        cw = ir._coefficient(on["wheel_speed_rad_s"], run.fs_hz, F_MOD, slow=slow)
        swing.append(abs(cw) * r / rig.speed_m_s)
        ct = ir._coefficient(on["torque_nm"], run.fs_hz, F_MOD, slow=slow)
        t_amp.append(abs(ct))
        w_amp.append(abs(cw))
        coa.append(float(on["torque_nm"].mean()) / (r * n))
    c = (2 * math.pi * F_MOD * rig.wheel_inertia_kg_m2 * rig.speed_m_s
         / (r * r * n))
    return {"coa": np.array(coa), "phase": np.array(phase), "swing": np.array(swing),
            "t_amp": np.array(t_amp), "w_amp": np.array(w_amp), "P": p, "C": c}


def measured_c(rig: ir.OrbitRig, case: dict, phase_deg: np.ndarray, se_deg: np.ndarray,
               ratio_noise: np.ndarray):
    """C from the amplitudes with the drawn phases and a relative error ``ratio_noise`` on
    each step's amplitude ratio."""
    return constant_from_amplitudes(case["t_amp"] * (1.0 + ratio_noise), case["w_amp"],
                                    phase_deg, se_deg, rig.speed_m_s, F_MOD,
                                    wheel_radius_m=rig.wheel_radius_m,
                                    normal_load_n=rig.normal_load_n)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--draws", type=int, default=10)
    ap.add_argument("--noise-deg", type=float, default=0.3)
    ap.add_argument("--depths", type=float, nargs="+", default=[0.95, 0.9, 0.86])
    ap.add_argument("--mu", type=float, nargs="+", default=[0.2, 0.35])
    ap.add_argument("--seed", type=int, default=3)
    ap.add_argument("--c-modes", nargs="+", default=["not given", "amplitudes", "given"],
                    choices=["not given", "amplitudes", "given"])
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)
    t0 = time.perf_counter()
    print(f"phase noise {args.noise_deg} deg per step, {args.draws} draws + 1 noise-free per "
          "case; determined = closed and half width <= 10 %")
    print("| shape | mu | u_max | P (truth) | C | fits | determined | median err | worst err "
          "| coverage |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    totals = {key: [0, 0, 0, []] for key in args.c_modes}
    j_err = []
    for name, k_a, k_s in SHAPES:
        for mu in args.mu:
            rig = ir.OrbitRig(mu=mu, k_a=k_a, k_s=k_s)
            for u_max in args.depths:
                case = simulate_case(rig, u_max)
                if case is None:
                    print(f"| {name} | {mu:g} | {u_max:.0%} | - | - | 0 | top step beyond "
                          "the creepage 0.2 | | | |")
                    continue
                se = np.full(FRACTIONS.size, args.noise_deg)
                est = measured_c(rig, case, case["phase"], se, np.zeros(FRACTIONS.size))
                j_err.append(est.inertia_kg_m2 / rig.wheel_inertia_kg_m2 - 1.0)
                print(f"| {name} | {mu:g} | {u_max:.0%} | inertia from the amplitudes "
                      f"{est.inertia_kg_m2:.4f} (true {rig.wheel_inertia_kg_m2:g}: "
                      f"{100 * j_err[-1]:+.2f} %, stated +-{100 * est.rel_se:.2f} %) "
                      "| | | | | | |", flush=True)
                for key in args.c_modes:
                    n = det = cov = 0
                    errs = []
                    for d in range(args.draws + 1):
                        noise = 0.0 if d == 0 else args.noise_deg
                        ph = case["phase"] + noise * rng.standard_normal(FRACTIONS.size)
                        c, c_rel = (case["C"] if key == "given" else None), 0.0
                        if key == "amplitudes":
                            est = measured_c(rig, case, ph, se, math.radians(noise)
                                             * rng.standard_normal(FRACTIONS.size))
                            c, c_rel = est.constant, est.rel_se
                        f = fit_available_adhesion_from_phase(
                            case["coa"], ph, se, constant=c, constant_rel_se=c_rel,
                            creepage_swing=case["swing"], speed_m_s=rig.speed_m_s,
                            probe=False)
                        if f is None:
                            continue
                        n += 1
                        top = f.high if f.closed else math.inf
                        cov += f.lower_bound <= case["P"] * (1 + 1e-9) <= top * (1 + 1e-9)
                        if f.determined:
                            det += 1
                            errs.append(abs(f.estimate / case["P"] - 1))
                    totals[key][0] += n
                    totals[key][1] += det
                    totals[key][2] += cov
                    totals[key][3] += errs
                    med = f"{100 * np.median(errs):.2f} %" if errs else "-"
                    wst = f"{100 * np.max(errs):.2f} %" if errs else "-"
                    print(f"| {name} | {mu:g} | {u_max:.0%} | {case['P']:.4f} | {key} | {n} | "
                          f"{det}/{n} | {med} | {wst} | {cov}/{n} |", flush=True)
    for key, (n, det, cov, errs) in totals.items():
        within = sum(e <= 0.03 for e in errs)
        print(f"C {key}: determined {det}/{n}, within 3 % {within}/{det}, worst "
              f"{100 * max(errs, default=math.nan):.2f} %, covered {cov}/{n}")
    if j_err:
        print(f"inertia from the noise-free amplitudes: {len(j_err)} cases, error "
              f"{100 * min(j_err):+.2f} .. {100 * max(j_err):+.2f} %")
    print(f"wall time {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
