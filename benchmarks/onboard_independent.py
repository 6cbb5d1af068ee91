"""The on-board estimator on runs NOT made by torquemod's twin (issue 10's hidden check):
prints figures, asserts nothing.

Runs come from :mod:`torquemod.twins.independent.train` (its own vehicle, a tanh or Burckhardt creep
law instead of Polach, a friction map dry 0.35 / wet 0.20 / leaves 0.10 / dry 0.35, a 4-Hz
modulation, torque and speed at the motor behind a gear ratio, a 10-Hz radar in its own MDF4
channel group, no position channel, logger names mapped in ``[channels]``). Each is written
to MDF4 + run.toml and read back by ``torquemod.ontrain.run.run_onboard`` with the default
settings (what a hidden run.toml without ``[onboard]`` gets). Against the generator's truth,
per friction segment: rows, the share with mu, the median |mu error|/mu where given, the
coverage of the 95 % interval where given, how often the lower bound (``mu_low_95`` on rows
without mu) exceeds the true mu, ``low_adhesion`` flags at <= 50 % true utilisation; and
diagnostics: the median ratio of the measured creep coefficient to the truth on steady
windows, the median phase standard error; the rows' interval coverage over all segments;
the per-segment table (segments.csv against the truth: best fit, 95 % interval, lower
bound, determined, error, depth reached) and its counts; and seconds of run per CPU
second (end to end: reading MDF4, estimating, writing figures and tables). Then a driver's
constant demand into a leaf patch (low_adhesion delay, false flags on dry rail) and the
estimator's own speed.

    python benchmarks/onboard_independent.py [--seeds 2] [--laws tanh burckhardt]
        [--depth 0.8 0.9] [--eccentricity 0.002 0.0] [--ratio-bounds 1 7]
        [--coupling 2e6 [--declare-drive-line]] [--torque-lag 0.004] [--declare-sensors]
        [--sample-rate 500]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from torquemod.ontrain.run import run_onboard
from torquemod.twins.independent.compare import match_segments
from torquemod.twins.independent.train import (
    FrictionSegment,
    IndependentRunSpec,
    segment_names,
    write_independent_run,
)


def evaluate(spec: IndependentRunSpec, track, truth) -> dict[str, dict]:
    """Per segment figures of one run (rows matched to the truth by time)."""
    t = track
    ts = t["time_s"].to_numpy()
    mu_t = np.interp(ts, truth["time_s"], truth["mu"])
    util = np.interp(ts, truth["time_s"], truth["utilisation"])
    k_t = np.interp(ts, truth["time_s"], truth["creep_coefficient"])
    cond = segment_names(spec, np.interp(ts, truth["time_s"], truth["position_m"]))
    mu = t["mu"].to_numpy()
    lo, hi = t["mu_low_95"].to_numpy(), t["mu_high_95"].to_numpy()
    given = np.isfinite(mu)
    steady = (t["dc_step_ratio"] <= 0.25).to_numpy() if "dc_step_ratio" in t else \
        np.ones(len(t), bool)
    out = {}
    for c in dict.fromkeys(cond):
        s = cond == c
        g = s & given
        nb = s & ~given
        low = s & (util <= 0.5)
        ks = s & steady & np.isfinite(t["creep_coefficient"].to_numpy())
        out[c] = {
            "rows": int(s.sum()), "given": int(g.sum()),
            "err": list(np.abs(mu[g] / mu_t[g] - 1)),
            "mu_given": list(mu[g]), "mu_true": float(np.median(mu_t[s])),
            "covered": int(((lo[g] <= mu_t[g]) & (mu_t[g] <= hi[g])).sum()),
            "lb_rows": int(nb.sum()), "lb_above": int((lo[nb] > mu_t[nb]).sum()),
            "la_low": int(t["low_adhesion"].to_numpy()[low].sum()), "low_rows": int(low.sum()),
            "k_ratio": list(t["creep_coefficient"].to_numpy()[ks] / k_t[ks]),
            "phase_se": list(t["phase_se_deg"].to_numpy()[s]),
        }
    return out


def segment_rows(spec: IndependentRunSpec, res, truth, run: str) -> list[dict]:
    """The estimator's per-segment table (``segments.csv``) against the truth: for each true
    friction segment, the estimated segment overlapping it most (positions mapped to the
    truth's through the rows' times; :func:`torquemod.twins.independent.compare.match_segments`),
    its best fit, interval, whether determined, and the error of the best fit."""
    out = []
    for s, best in match_segments(spec, res.track, res.segment_table(), truth):
        row = {"run": run, "segment": s.name, "truth": s.mu, "estimate": np.nan,
               "low": np.nan, "high": np.nan, "lower_bound": np.nan, "determined": False,
               "error": np.nan, "law": "-", "coa_reached": np.nan}
        if best is not None:
            est = best["adhesion_available_best_fit"]
            row.update(estimate=est, low=best["adhesion_available_low_95"],
                       high=best["adhesion_available_high_95"],
                       lower_bound=best["adhesion_available_lower_bound"],
                       determined=bool(best["determined"]), error=est / s.mu - 1,
                       law=best["best_law"] or "-", coa_reached=best["coa_reached"])
        out.append(row)
    return out


def print_segments(rows: list[dict]) -> None:
    """The per-segment table and its counts."""
    print(f"{'run':>14} {'segment':>7} {'truth':>6} {'best fit':>8} {'95 % interval':>15} "
          f"{'LB':>6} {'det.':>4} {'error':>7} {'reached':>7} {'law':>14}")
    for r in rows:
        hi = f"{r['high']:.3f}" if np.isfinite(r["high"]) else "open"
        print(f"{r['run']:>14} {r['segment']:>7} {r['truth']:>6.3f} {r['estimate']:>8.3f} "
              f"[{r['low']:.3f}, {hi:>5}] {r['lower_bound']:>6.3f} "
              f"{'yes' if r['determined'] else 'no':>4} {100 * r['error']:>6.1f}% "
              f"{r['coa_reached'] / r['truth']:>6.0%} {r['law']:>14}")
    n = len(rows)
    det = [r for r in rows if r["determined"]]
    within = sum(abs(r["error"]) <= 0.10 for r in det)
    best_within = sum(abs(r["error"]) <= 0.10 for r in rows if np.isfinite(r["error"]))
    cov = sum(r["low"] <= r["truth"] <= (r["high"] if np.isfinite(r["high"]) else np.inf)
              for r in rows if np.isfinite(r["low"]))
    lb = sum(r["lower_bound"] > r["truth"] for r in rows)
    print(f"segments determined {len(det)}/{n}, determined and within 10 %: {within}/{n}; "
          f"best fit within 10 % (determined or not): {best_within}/{n}; truth inside the "
          f"segment's 95 % interval: {cov}/{n}; lower bound above the truth: {lb}/{n}")


def _merge(acc: dict, new: dict) -> None:
    for c, d in new.items():
        a = acc.setdefault(c, {k: ([] if isinstance(v, list) else 0) for k, v in d.items()})
        for k, v in d.items():
            if k == "mu_true":
                a[k] = v
            else:
                a[k] = a[k] + v


#: every scenario's per-segment rows (the summary at the end)
SEGMENTS: list[dict] = []


def scenario(spec: IndependentRunSpec, seeds: int, out: Path, title: str) -> None:
    acc: dict = {}
    seg_rows: list[dict] = []
    run_s = cpu_s = 0.0
    delays: list[float] = []
    for seed in range(seeds):
        s = replace(spec, seed=seed)
        folder = out / f"run_{seed}"
        path, _ = write_independent_run(s, folder)
        c0 = time.process_time()
        res = run_onboard(path, out / f"res_{seed}", force=True)[0]
        cpu_s += time.process_time() - c0
        delays.append(1e3 * res.summary().get("measured_delay_s", float("nan")))
        import pandas as pd
        truth = pd.read_parquet(folder / "truth.parquet")
        run_s += float(truth["time_s"].iloc[-1] - truth["time_s"].iloc[0])
        _merge(acc, evaluate(s, res.track, truth))
        seg_rows += segment_rows(s, res, truth, f"{spec.law} seed {seed}")
    print(f"\n{title} ({seeds} seeds)")
    print(f"{'segment':>8} {'true mu':>7} {'rows':>5} {'mu given':>8} {'median mu':>9} "
          f"{'med |err|':>9} {'coverage':>8} {'LB>truth':>8} {'low_adh u<=.5':>13} "
          f"{'k/k_true':>8} {'phase se':>8}")
    for c, a in acc.items():
        med_mu = f"{np.median(a['mu_given']):.3f}" if a["given"] else "-"
        err = f"{100 * np.median(a['err']):.1f} %" if a["given"] else "-"
        cov = f"{100 * a['covered'] / a['given']:.0f} %" if a["given"] else "-"
        lb = f"{100 * a['lb_above'] / max(a['lb_rows'], 1):.1f} %"
        la = f"{a['la_low']}/{a['low_rows']}"
        kr = f"{np.median(a['k_ratio']):.3f}" if a["k_ratio"] else "-"
        print(f"{c:>8} {a['mu_true']:>7.2f} {a['rows']:>5} {100 * a['given'] / a['rows']:>7.0f}% "
              f"{med_mu:>9} {err:>9} {cov:>8} {lb:>8} {la:>13} {kr:>8} "
              f"{np.median(a['phase_se']):>7.2f}°")
    tot = {k: sum(a[k] for a in acc.values()) for k in ("given", "covered", "lb_rows",
                                                          "lb_above", "rows")}
    print(f"rows with mu (a closed interval): {tot['given']}/{tot['rows']}, truth inside "
          f"{tot['covered']}/{tot['given']} "
          f"({100 * tot['covered'] / max(tot['given'], 1):.1f} %); lower bound above the "
          f"truth in {tot['lb_above']}/{tot['lb_rows']} rows without mu "
          f"({100 * tot['lb_above'] / max(tot['lb_rows'], 1):.1f} %)")
    print("per segment (segments.csv: each segment between detected changes fitted from all "
          "its windows once it ended; error of the best fit):")
    print_segments(seg_rows)
    SEGMENTS.extend(seg_rows)
    print("net torque-behind-speed delay measured from the run and taken out: "
          + ", ".join(f"{d:.2f} ms" for d in delays))
    print(f"end to end (MDF4 read, estimate, write): {run_s / cpu_s:.0f} s of run per CPU s")


def low_adhesion(seeds: int, out: Path, law: str) -> None:
    """A driver's constant demand that needs 93 % of a leaf patch's adhesion, entered at
    800 m from dry rail (where it is 27 % of the adhesion): the delay from the moment the
    demand first needs >= 90 % of the available adhesion (truth) to the first low_adhesion
    row (at its window's end, when a live system has it), and false flags on dry rail at
    <= 50 % true utilisation (after the first 3 s)."""
    import pandas as pd
    spec0 = IndependentRunSpec(law=law, length_m=1400.0, segments=(
        FrictionSegment("dry", 0.0, 0.35, 110.0), FrictionSegment("leaves", 800.0, 0.10, 40.0)))
    n_r = spec0.normal_load_n * spec0.wheel_radius_m
    spec0 = replace(spec0, constant_torque_nm=0.93 * 0.10 * n_r)
    delays, false_rows, dry_rows = [], 0, 0
    for seed in range(seeds):
        spec = replace(spec0, seed=seed)
        path, _ = write_independent_run(spec, out / f"la_{seed}")
        res = run_onboard(path, out / f"la_res_{seed}", force=True)[0]
        t = res.track
        truth = pd.read_parquet(out / f"la_{seed}" / "truth.parquet")
        need = truth["dc_torque_nm"] / n_r / truth["mu"]
        t_90 = float(truth["time_s"][need >= 0.9].iloc[0])
        t_avail = t["time_s"] + res.config.window_periods / (2 * spec.modulation_frequency_hz)
        flagged = t_avail[(t_avail > t_90) & t["low_adhesion"]]
        delays.append(float(flagged.iloc[0]) - t_90 if len(flagged) else np.inf)
        ts = t["time_s"].to_numpy()
        util = np.interp(ts, truth["time_s"], truth["utilisation"])
        pos = np.interp(ts, truth["time_s"], truth["position_m"])
        dry = (pos < 800.0 - spec.transition_m) & (util <= 0.5) & (ts > ts[0] + 3.0)
        false_rows += int(t["low_adhesion"].to_numpy()[dry].sum())
        dry_rows += int(dry.sum())
    print(f"\nlow adhesion ({law} law): constant demand = 93 % of the leaf patch's adhesion "
          f"({spec0.constant_torque_nm:.0f} N*m at the axle)")
    print("  delay from the demand first needing >= 90 % of the adhesion to low_adhesion "
          f"(window's end): {', '.join(f'{d:.2f} s' for d in delays)}")
    print(f"  false low_adhesion on dry rail at <= 50 % utilisation: {false_rows}/{dry_rows} "
          f"windows ({100 * false_rows / max(dry_rows, 1):.2f} %)")


def speed(out: Path) -> None:
    """CPU seconds of the estimator alone on the default independent run, best of three
    (:func:`onboard.estimator_cpu_s`, the twin benchmark's own timing)."""
    from onboard import estimator_cpu_s  # benchmarks/onboard.py, beside this script
    path, _ = write_independent_run(IndependentRunSpec(), out / "speed")
    rec_s, fs, best, fits = estimator_cpu_s(path)
    print(f"\nestimator alone: {rec_s:.0f} s recorded at {fs:g} Hz in {best:.2f} CPU s = "
          f"{rec_s / best:.0f} x real time ({fits} mu fits)")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--laws", nargs="+", default=["tanh", "burckhardt", "polach"])
    ap.add_argument("--depth", type=float, nargs="+", default=[0.8])
    ap.add_argument("--eccentricity", type=float, nargs="+", default=[0.002],
                    help="the motor encoder's once-per-revolution speed error (relative)")
    ap.add_argument("--ratio-bounds", type=float, nargs=2, default=None,
                    help="[onboard] ratio_bounds written into run.toml (default: none, "
                         "the estimator's defaults)")
    ap.add_argument("--coupling", type=float, default=None,
                    help="a compliant coupling motor-wheelset [N*m/rad, axle-referred] "
                         "(default: rigid drive line)")
    ap.add_argument("--declare-drive-line", action="store_true",
                    help="write the coupling and motor inertia into run.toml")
    ap.add_argument("--scenarios-only", action="store_true",
                    help="skip the driver's-demand runs and the speed measurement")
    ap.add_argument("--declare-sensors", action="store_true",
                    help="write the torque's lag and the speed's delay into run.toml")
    ap.add_argument("--torque-lag", type=float, default=None,
                    help="the torque signal's first-order lag [s] (default: the generator's)")
    ap.add_argument("--sample-rate", type=float, default=None,
                    help="the logger's sample rate [Hz] (default: the generator's 2000 Hz)")
    ap.add_argument("--no-calibrate", action="store_true",
                    help="[onboard] calibrate_delay = 0 (no delay measured from the run)")
    ap.add_argument("--onboard", nargs="+", default=[], metavar="KEY=VALUE",
                    help="further [onboard] settings written into run.toml (numbers)")
    args = ap.parse_args()
    onboard = {} if args.ratio_bounds is None else {"ratio_bounds": list(args.ratio_bounds)}
    for item in args.onboard:
        key, value = item.split("=", 1)
        onboard[key] = float(value)
    if args.no_calibrate:
        onboard["calibrate_delay"] = 0
    extra = {"onboard": onboard} if onboard else {}
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        for law in args.laws:
            for depth in args.depth:
                for ecc in args.eccentricity:
                    spec = IndependentRunSpec(law=law, levels=tuple(np.linspace(0.2, depth, 4)),
                                              encoder_eccentricity=ecc, extra_toml=extra,
                                              coupling_stiffness_nm_rad=args.coupling,
                                              declare_drive_line=args.declare_drive_line,
                                              declare_sensor_dynamics=args.declare_sensors)
                    if args.torque_lag is not None:
                        spec = replace(spec, torque_lag_s=args.torque_lag)
                    if args.sample_rate is not None:
                        spec = replace(spec, sample_rate_hz=args.sample_rate)
                    tag = f"{law}_{depth}_{ecc}"
                    out = Path(tmp) / tag
                    scenario(spec, args.seeds, out,
                             f"{law} creep law, staircase to {depth:.0%} of the adhesion, "
                             f"encoder eccentricity {ecc:g}"
                             + (f", [onboard] {onboard}" if onboard else "")
                             + (f", coupling {args.coupling:g} N*m/rad"
                                f"{' (declared)' if args.declare_drive_line else ''}"
                                if args.coupling else "")
                             + f", torque lag {spec.torque_lag_s * 1e3:g} ms"
                             + (" (declared)" if args.declare_sensors else "")
                             + f", logger {spec.sample_rate_hz:g} Hz")
        if len(SEGMENTS) > len(args.laws) * 4:
            print("\nall scenarios:")
            print_segments(SEGMENTS)
        if args.scenarios_only:
            return
        for law in args.laws:
            low_adhesion(args.seeds, Path(tmp) / f"la_{law}", law)
        speed(Path(tmp))
    print(f"\n(benchmark wall time {time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
