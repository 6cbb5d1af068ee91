"""On-board estimator against the train twin (issue 10): prints figures, asserts nothing.

1. Measurement runs (the default twin run: dry, wet, leaves, friction modifier, dry; DC
   torque staircase to ``--depth`` of the available adhesion) over ``--seeds`` seeds: per
   segment the share of rows with mu, the median error of mu where given, the coverage of
   the 95 % interval, and how often the lower bound exceeds the truth.
2. Low adhesion: constant demand that needs 93 % of the adhesion of a leaf patch entered
   from dry rail (where it is ~24 % of the available adhesion): the delay from entering the
   patch to the first low_adhesion row, and false flags on the dry part.
3. Speed: recorded seconds per CPU second of the estimator alone on one core (and end to end
   with reading and writing, per measurement run).

    python benchmarks/onboard.py [--seeds 3] [--depth 0.8 0.9]
"""

from __future__ import annotations

import argparse
import dataclasses
import tempfile
import time
from pathlib import Path

import numpy as np
from onboard_independent import print_segments  # beside this script

from torquemod.onboard.run import run_onboard
from torquemod.train import load_train_config, run_train_simulation
from torquemod.train.params import CONDITIONS, Leg, Segment


def _truth_at(track, truth, col):
    return np.interp(track["position_m"], truth["position_m"], truth[col])


def natural(seeds: int, out: Path) -> None:
    """No probe: the driver's own demand (hold 20 m/s, accelerate with 12 kN*m through dry
    into wet rail, coast, brake with -8 kN*m, hold the speed), the axle alone."""
    cfg = load_train_config()
    legs = (Leg(until_m=800.0, mode="speed", speed_m_s=20.0),
            Leg(until_m=2000.0, mode="torque", torque_nm=12_000.0),
            Leg(until_m=2500.0, mode="coast"),
            Leg(until_m=3100.0, mode="torque", torque_nm=-8_000.0),
            Leg(until_m=4000.0, mode="speed", speed_m_s=20.0))
    cfg = dataclasses.replace(cfg, controller=dataclasses.replace(cfg.controller, legs=legs))
    _segment_stats(cfg, seeds, out, "natural driving, no probe", "nat")


def measurement(depth: float, seeds: int, out: Path, a_ratio: float | None = None) -> None:
    cfg = load_train_config()
    legs = tuple(dataclasses.replace(leg, levels=tuple(np.linspace(0.2, depth, 4)))
                 for leg in cfg.controller.legs)
    cfg = dataclasses.replace(cfg, controller=dataclasses.replace(cfg.controller, legs=legs))
    if a_ratio is not None:  # the same conditions with weaker falling friction (Polach's A)
        segs = tuple(dataclasses.replace(s, polach=dataclasses.replace(s.polach,
                                                                       a_ratio=a_ratio))
                     for s in cfg.track.segments)
        cfg = dataclasses.replace(cfg, track=dataclasses.replace(cfg.track, segments=segs))
    falling = "Polach's presets" if a_ratio is None else f"A = {a_ratio} in every segment"
    _segment_stats(cfg, seeds, out, f"{falling}, staircase to {depth:.0%} of the available "
                   "adhesion", f"{depth}_{a_ratio}")


def _segment_stats(cfg, seeds: int, out: Path, title: str, tag: str) -> None:
    """Run ``cfg`` over the seeds and print per friction segment: rows, share with mu, median
    error, coverage, lower bound above the truth, low_adhesion at <= 50 % utilisation."""
    stats: dict[str, list] = {}
    seg_rows: list[dict] = []
    wall = sim_s = 0.0
    for seed in range(seeds):
        run = out / f"run{tag}_{seed}"
        run_train_simulation(cfg, run, seed=seed, force=True)
        res = run_onboard(run / "run.toml", out / f"res{tag}_{seed}", force=True)[0]
        wall += res.seconds
        t, tr = res.track, res.truth
        sim_s += float(t["time_s"].iloc[-1] - t["time_s"].iloc[0])
        mu_true = _truth_at(t, tr, "mu")
        util = _truth_at(t, tr, "utilisation")
        cond = np.array(tr["condition"])[np.clip(np.searchsorted(
            tr["position_m"], t["position_m"]), 0, len(tr) - 1)]
        seg_rows += _segment_rows(res, tr, f"{tag} seed {seed}")
        for c in dict.fromkeys(cond):
            sel = cond == c
            part, mt = t[sel], mu_true[sel]
            given = part["mu"].notna().to_numpy()
            s = stats.setdefault(c, [0, 0, [], 0, 0, 0, 0, 0])
            low_util = util[sel] <= 0.5
            s[6] += int(part["low_adhesion"].to_numpy()[low_util].sum())
            s[7] += int(low_util.sum())
            s[0] += sel.sum()
            s[1] += given.sum()
            s[2] += list(np.abs(part["mu"].to_numpy()[given] / mt[given] - 1))
            s[3] += int(((part["mu_low_95"].to_numpy()[given] <= mt[given])
                         & (mt[given] <= part["mu_high_95"].to_numpy()[given])).sum())
            lb = part["mu_low_95"].to_numpy()[~given]
            s[4] += int((lb > mt[~given]).sum())
            s[5] += int((~given).sum())
    print(f"\nmeasurement runs ({title}), {seeds} seeds")
    print(f"{'condition':>18} {'rows':>6} {'mu given':>9} {'median err':>11} "
          f"{'coverage':>9} {'LB > truth':>11} {'low_adh. at u<=0.5':>19}")
    for c, (n, g, err, cov, lb_bad, n_lb, la, n_la) in stats.items():
        med = f"{100 * np.median(err):.1f} %" if err else "-"
        covs = f"{100 * cov / g:.0f} %" if g else "-"
        print(f"{c:>18} {n:>6} {100 * g / n:>8.0f}% {med:>11} {covs:>9} "
              f"{100 * lb_bad / max(n_lb, 1):>10.1f}% {la:>9}/{n_la:<5} windows")
    print("per segment (segments.csv against the twin's available adhesion):")
    print_segments(seg_rows)
    print(f"end to end (reading MDF4, estimating, writing): {sim_s / wall:.0f} x real time")


def _segment_rows(res, tr, run: str) -> list[dict]:
    """The twin's friction segments (runs of one ``condition`` in the truth; the truth's
    ``mu``, the available adhesion, as their median) against the estimator's per-segment
    table: the estimated segment overlapping each most."""
    x = tr["position_m"].to_numpy()
    cond = np.asarray(tr["condition"])
    cuts = np.flatnonzero(cond[1:] != cond[:-1]) + 1
    segs = res.segment_table()
    rows = []
    for a, b in zip(np.r_[0, cuts], np.r_[cuts, cond.size], strict=True):
        lo, hi = x[a], x[b - 1]
        row = {"run": run, "segment": str(cond[a])[:7],
               "truth": float(np.median(tr["mu"].to_numpy()[a:b])), "estimate": np.nan,
               "low": np.nan, "high": np.nan, "lower_bound": np.nan, "determined": False,
               "error": np.nan, "law": "-", "coa_reached": np.nan}
        ov = [min(hi, r.end_m) - max(lo, r.start_m) for r in segs.itertuples()]
        if ov and max(ov) > 0:
            r = segs.iloc[int(np.argmax(ov))]
            est = r["adhesion_available_best_fit"]
            row.update(estimate=est, low=r["adhesion_available_low_95"],
                       high=r["adhesion_available_high_95"],
                       lower_bound=r["adhesion_available_lower_bound"],
                       determined=bool(r["determined"]), error=est / row["truth"] - 1,
                       law=r["best_law"] or "-", coa_reached=r["coa_reached"])
        rows.append(row)
    return rows


def low_adhesion(seeds: int, out: Path) -> None:
    base = load_train_config()
    v = base.vehicle
    from torquemod.train.dynamics import adhesion_peak
    sx = v.stiffness_x_n()
    lv = CONDITIONS["leaves"]
    peak = float(adhesion_peak(20.0, v.normal_load_n, sx, lv.mu0, lv.a_ratio, lv.b_s_m,
                               lv.k_a, lv.k_s)[0])
    torque = 0.93 * peak * v.normal_load_n * v.wheel_radius_m
    force = torque / v.wheel_radius_m
    track = dataclasses.replace(base.track, length_m=1400.0, segments=(
        Segment(0.0, "dry", CONDITIONS["dry"]), Segment(800.0, "leaves", lv)))
    ctl = dataclasses.replace(base.controller, legs=(
        Leg(until_m=1400.0, mode="torque", torque_nm=torque, others_force_n=-force + 1500),))
    cfg = dataclasses.replace(base, track=track, controller=ctl)
    delays, delays_90, false_rows, dry_rows = [], [], 0, 0
    for seed in range(seeds):
        run = out / f"la_{seed}"
        run_train_simulation(cfg, run, seed=seed, force=True)
        res = run_onboard(run / "run.toml", out / f"la_res_{seed}", force=True)[0]
        t, tr = res.track, res.truth
        t_in = float(np.interp(800.0 - track.transition_m / 2, tr["position_m"], tr["time_s"]))
        # a row describes its window's centre; a live system has it at the window's end
        t_avail = t["time_s"] + res.config.window_periods / (2 * cfg.modulation_frequency_hz)
        flagged = t_avail[(t_avail > t_in) & t["low_adhesion"]]
        delays.append(float(flagged.iloc[0]) - t_in if len(flagged) else np.inf)
        # when the demand first needs >= 90 % of the available adhesion (in the transition)
        demand = tr["dc_torque_nm"] / (tr["normal_load_n"] * v.wheel_radius_m)
        need = tr["time_s"][(demand >= 0.9 * tr["adhesion_peak"]) & (tr["time_s"] > t_in - 2.0)]
        t_90 = float(need.iloc[0]) if len(need) else np.nan
        flagged = t_avail[(t_avail > t_90) & t["low_adhesion"]]
        delays_90.append(float(flagged.iloc[0]) - t_90 if len(flagged) else np.inf)
        util = _truth_at(t, tr, "utilisation")
        dry = (t["position_m"] < 800.0 - track.transition_m).to_numpy() & (util <= 0.5)
        dry &= (t["time_s"] > 3.0).to_numpy()  # after the start-up transient
        false_rows += int(t["low_adhesion"].to_numpy()[dry].sum())
        dry_rows += int(dry.sum())
    print(f"\nlow adhesion: demand = 93 % of the leaf patch's adhesion ({torque:.0f} N*m)")
    print(f"  delay from the middle of the 20-m transition into the patch to low_adhesion "
          f"(at the window's end): {', '.join(f'{d:.2f} s' for d in delays)}")
    print(f"  delay from the moment the demand needs >= 90 % of the available adhesion: "
          f"{', '.join(f'{d:.2f} s' for d in delays_90)}")
    print(f"  false low_adhesion on dry rail at <= 50 % utilisation: {false_rows}/{dry_rows} "
          f"windows ({100 * false_rows / max(dry_rows, 1):.2f} %)")


def estimator_cpu_s(run_toml: Path, repeat: int = 3) -> tuple[float, float, float, int]:
    """The estimator alone on the first axle of ``run_toml`` (arrays in memory, fed in 30-s
    chunks as the batch command does), best of ``repeat``: (recorded s, sample rate [Hz],
    CPU s, mu fits)."""
    from torquemod.io import read_recording
    from torquemod.io.run import read_run
    from torquemod.onboard.estimator import OnboardEstimator
    from torquemod.onboard.run import _AxleSignals
    run = read_run(run_toml)
    e = run.recordings[0]
    rec = read_recording(e.path, group=e.group, channel_map=run.channel_map,
                         sample_rate_hz=e.sample_rate_hz)
    arrays = _AxleSignals(run, e, rec.channels, rec.fs_hz, [])(rec.channels, 0, rec.t0_s)
    n, step = arrays[0].size, round(30 * rec.fs_hz)
    best = np.inf
    for _ in range(repeat):
        est = OnboardEstimator(run.vehicle, run.modulation_frequency_hz, rec.fs_hz)
        t0 = time.process_time()
        for a in range(0, n, step):
            est.feed(*(x[a:a + step] for x in arrays))
        best = min(best, time.process_time() - t0)
    return n / rec.fs_hz, rec.fs_hz, best, est.tracker.n_fits


def speed(out: Path) -> None:
    """CPU seconds of the estimator alone on the default twin run: simulated seconds per
    CPU second (:func:`estimator_cpu_s`)."""
    run_train_simulation(load_train_config(), out / "speed", seed=0, force=True)
    rec_s, _, best, fits = estimator_cpu_s(out / "speed" / "run.toml")
    print(f"\nestimator alone: {rec_s:.0f} s recorded in {best:.2f} CPU s = "
          f"{rec_s / best:.0f} x real time per axle on one core ({fits} mu fits)")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--depth", type=float, nargs="+", default=[0.8, 0.9])
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        t0 = time.perf_counter()
        for depth in args.depth:
            measurement(depth, args.seeds, out)
            measurement(depth, args.seeds, out, a_ratio=0.95)
        natural(args.seeds, out)
        low_adhesion(args.seeds, out)
        speed(out)
        print(f"\n(benchmark wall time {time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
