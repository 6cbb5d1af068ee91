"""The V-Track twin's discretisation error against its recorded RK4 step.

Run: ``python benchmarks/twin_step_accuracy.py [--steps 12 16 20 24] [--ref 4] [--quick]
[--quiet] [--only LABEL] [--settle-same] [--check-ref]`` (all groups, four candidates: ~4 min
on one core).

For every configuration a user runs -- the points of ``examples/sweep_vtrack_conditions.toml``
(five contact conditions, 4 and 8.5 km/h, 2500 and 6000 N, modulation 1/2/4 Hz at 8 and 4 N*m,
DC torques up to 0.95 of the creep-curve peak), the default experiment at 2 and 3 Hz, the
default experiment sampled at 10 kHz, and corners (dry contact at 2 and 4 km/h, where the
creep-force damping is fastest, vtrack at 2 km/h, dry and leaves at 8 Hz) -- the twin is run
(:func:`simulate_batch`, truth only, noise-free by construction: the truth is taken from the
integrated states) with
``procedure.samples_per_step`` set to each candidate and to a short reference step (``--ref``
samples, its settling at the same step), bypassing the step check (a candidate of 0: the step
the configuration's check sets, i.e. the twin as shipped). Printed per configuration
group and candidate: the largest difference from the reference of

* the simulated phase of a whole step (the wobble fitted out) [deg],
* the phase of one platform revolution [deg],
* the mean creepage [-] and the mean CoA [-] of a step,

together with ``lambda*h`` of the explicit part (``params.explicit_rate``) and ``2*pi*f*h``
of the modulation at that step. ``--check-ref`` also runs half the reference step on the
default experiment, to show that the reference itself has converged.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import time
from pathlib import Path

from torquemod.sweep.conditions import conditions
from torquemod.sweep.evaluate import point_config, tasks
from torquemod.sweep.spec import load_sweep
from torquemod.twins.vtrack.params import explicit_rate
from torquemod.twins.vtrack.rig import steps as _steps
from torquemod.twins.vtrack.simulate import load_config, simulate_batch
from torquemod.twins.vtrack.theory import creep_curve_peak

ROOT = Path(__file__).resolve().parents[1]
#: the example sweep's DC torques, fractions of the creep curve's peak torque
FRACTIONS = (0.0, 0.3, 0.5, 0.6, 0.7, 0.8, 0.9, 0.95)


def with_step(config, sps: int):
    """``config`` with ``sps`` samples a recorded RK4 step (no guard)."""
    return dataclasses.replace(config, procedure=dataclasses.replace(
        config.procedure, samples_per_step=int(sps), substeps=1))


def run(configs, sps: int, settle_same: bool):
    """Truth of ``configs`` at ``sps`` samples a step (0: each configuration's own, as its
    step check set it); ``settle_same``: settling at that step too (the reference), else
    the twin's own settling rule."""
    saved = _steps.SETTLE_STEPS
    if settle_same:
        _steps.SETTLE_STEPS = 1
    try:
        return simulate_batch([with_step(c, sps) if sps else c for c in configs], seed=1,
                              large_signal=False)
    finally:
        _steps.SETTLE_STEPS = saved


def differences(ref_points, points) -> dict[str, float]:
    """Largest |difference| over the unslipped steps both runs share."""
    d = {"phase_step_deg": 0.0, "phase_rev_deg": 0.0, "creepage": 0.0, "coa": 0.0,
         "creepage_rel": 0.0, "n_steps": 0, "worst_step": 0}
    for rp, p in zip(ref_points, points, strict=True):
        for a, b in zip(rp.steps, p.steps, strict=False):
            if a["slipped"] or b["slipped"]:
                break
            sa, sb = a["simulated"], b["simulated"]
            d["n_steps"] += 1
            if abs(sa["phase_deg"] - sb["phase_deg"]) > d["phase_step_deg"]:
                d["phase_step_deg"] = abs(sa["phase_deg"] - sb["phase_deg"])
                d["worst_step"] = a["step"]
            for ca, cb in zip(sa["cycles"], sb["cycles"], strict=True):
                d["phase_rev_deg"] = max(d["phase_rev_deg"],
                                         abs(ca["phase_deg"] - cb["phase_deg"]))
            dxi = abs(sa["creepage_mean"] - sb["creepage_mean"])
            d["creepage"] = max(d["creepage"], dxi)
            d["creepage_rel"] = max(d["creepage_rel"], dxi / max(abs(sa["creepage_mean"]), 1e-12))
            d["coa"] = max(d["coa"], abs(sa["coa_mean"] - sb["coa_mean"]))
    return d


def corner(condition: str, speed_km_h: float, frequency_hz: float):
    """A configuration outside the example sweep: the sweep's steps (fractions of the peak)
    and fixed settings at another speed or modulation frequency."""
    config = load_config(overrides={"contact": conditions()[condition].as_dict(),
                                    "rig": {"speed_km_h": speed_km_h},
                                    "modulation": {"frequency_hz": frequency_hz},
                                    "procedure": {"cycles_per_step": 2, "settle_s": 3.0}})
    _, t_peak = creep_curve_peak(config.rig)
    return dataclasses.replace(config, procedure=dataclasses.replace(
        config.procedure, dc_torques_nm=tuple(f * t_peak for f in FRACTIONS)))


def groups(quick: bool, quiet: bool = False) -> dict[str, list]:
    """Configuration groups: label -> list of SimConfig; ``quiet``: disturbances (speed
    wobble, sleepers, rail joints, encoder eccentricity) off, as the twin-vs-theory
    comparisons run."""
    spec = load_sweep(ROOT / "examples" / "sweep_vtrack_conditions.toml")
    out: dict[str, list] = {}
    for task in tasks(spec):
        if quick and task.params.get("modulation.amplitude_nm") == 4.0:
            continue
        config, _ = point_config(task)
        # the sweep's fixed settings are in the overrides already
        p = task.params
        label = (f"{p.get('contact.condition', 'vtrack')} "
                 f"{p.get('rig.speed_km_h', 7.0):g} km/h {p.get('rig.normal_load_n', 4200.0):g} N "
                 f"{p['modulation.frequency_hz']:g} Hz")
        out.setdefault(label, []).append(config)
    for f in (2.0, 3.0):
        out[f"default {f:g} Hz"] = [load_config(overrides={"modulation": {"frequency_hz": f}})]
        out[f"default {f:g} Hz, 10 kHz"] = [load_config(overrides={
            "modulation": {"frequency_hz": f}, "sensors": {"sample_rate_hz": 10000.0}})]
    # the corners: the creep damping rate grows as 1/V (explicit_rate), the modulation to 8 Hz
    for cond, kmh, f in (("dry", 2.0, 2.0), ("dry", 4.0, 4.0), ("vtrack", 2.0, 2.0),
                         ("dry", 7.0, 8.0), ("leaves", 7.0, 8.0)):
        out[f"corner: {cond} {kmh:g} km/h 4200 N {f:g} Hz"] = [corner(cond, kmh, f)]
    if quiet:
        out = {k: [dataclasses.replace(c, disturbances=dataclasses.replace(
            c.disturbances, enabled=False)) for c in v] for k, v in out.items()}
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--steps", type=int, nargs="+", default=[12, 16, 20, 24],
                    help="recorded steps to test [samples at 16 670 Hz]; 0: the step the "
                         "configuration's step check sets (the twin as shipped)")
    ap.add_argument("--ref", type=int, default=4, help="reference step [samples at 16 670 Hz]")
    ap.add_argument("--quick", action="store_true", help="8 N*m points of the sweep only")
    ap.add_argument("--only", default="", help="run groups whose label contains this")
    ap.add_argument("--quiet", action="store_true",
                    help="disturbances off (wobble, sleepers, joints), as twin-vs-theory runs")
    ap.add_argument("--settle-same", action="store_true",
                    help="candidates settle at their recorded step (not twice it)")
    ap.add_argument("--check-ref", action="store_true",
                    help="also compare the reference with half its step (default experiment)")
    args = ap.parse_args()
    rows = []
    for label, configs in groups(args.quick, args.quiet).items():
        if args.only and args.only not in label:
            continue
        fs = configs[0].sensors.sample_rate_hz
        scale = fs / 16670.0  # candidate steps are given at 16 670 Hz: the same step [s]
        ref_sps = max(1, round(args.ref * scale))
        t0 = time.process_time()
        ref = run(configs, ref_sps, settle_same=True)
        lam = max(explicit_rate(c.rig) for c in configs)
        f_mod = max(c.modulation.actual_frequency_hz for c in configs)
        for s in args.steps:
            sps = max(1, round(s * scale)) if s else 0
            h = (sps or min(c.procedure.samples_per_step for c in configs)) / fs
            d = differences(ref, run(configs, sps, settle_same=args.settle_same))
            rows.append((label, s, lam * h, 2 * math.pi * f_mod * h, d))
            print(f"{label:42s} {round(h * fs):3d} smp h={h * 1e3:.3f} ms lam*h={lam * h:.3f} "
                  f"w*h={2 * math.pi * f_mod * h:.4f} | phase step {d['phase_step_deg']:.2e} "
                  f"rev {d['phase_rev_deg']:.2e} deg | creepage {d['creepage']:.1e} "
                  f"({d['creepage_rel']:.1e} rel) | CoA {d['coa']:.1e} | {d['n_steps']} steps "
                  f"(worst {d['worst_step']})",
                  flush=True)
        print(f"  ({time.process_time() - t0:.1f} CPU-s)", flush=True)
        if args.check_ref and label.startswith("default") and "kHz" not in label:
            half = run(configs, max(1, ref_sps // 2), settle_same=True)
            d = differences(half, ref)
            print(f"  reference {ref_sps} vs {max(1, ref_sps // 2)} samples: phase step "
                  f"{d['phase_step_deg']:.2e} rev {d['phase_rev_deg']:.2e} deg", flush=True)
    print("\nworst over all configurations, per candidate step:")
    for s in args.steps:
        sel = [r for r in rows if r[1] == s]
        if not sel:
            continue
        worst = {k: max(r[4][k] for r in sel) for k in ("phase_step_deg", "phase_rev_deg",
                                                       "creepage", "coa")}
        arg = max(sel, key=lambda r: r[4]["phase_rev_deg"])
        print(f"{s:3d} samples: phase step {worst['phase_step_deg']:.2e} deg, revolution "
              f"{worst['phase_rev_deg']:.2e} deg (at {arg[0]}), creepage "
              f"{worst['creepage']:.1e}, CoA {worst['coa']:.1e}; "
              f"max lam*h {max(r[2] for r in sel):.3f}, max w*h {max(r[3] for r in sel):.4f}")


if __name__ == "__main__":
    main()
