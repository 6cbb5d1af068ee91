"""The chain's phase and modulation frequency against an independent rig (prints figures,
asserts nothing).

The records come from ``tests/independent_rig.py`` (the rig's equations written apart from
torquemod, integrated by scipy's DOP853; noise-free, 2 kHz). Each record is one cycle of
``torquemod.chain`` with ``ProcessingConfig.for_modulation`` of its nominal frequency (what
a manifest that gives only the frequency gets).

1. Steady speed: |chain - periodic orbit| [deg] per modulation frequency (0.5-8 Hz, at
   least 7 periods per record) and utilisation (30-90 % of the creep curve's peak).
2. A slow speed wobble (three lines at 0.2-0.6 Hz, ``--rms`` of the set speed, plus a third
   and a sixth of it once and twice per revolution) at 60-90 % and 1, 2 and 4 Hz: the error
   of each method with the defaults against the phase docs/processing.md defines for a
   moving operating point (over the span the chain analyses); for scale the paper's three
   middle periods and the full slow band; the modulation frequency's error; and each
   method's noise, the standard deviation over copies with white noise added.

    python benchmarks/chain_accuracy.py [--seeds 2] [--rms 0.002 0.003] [--skip-steady]
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
from torquemod import chain
from torquemod.config import ProcessingConfig
from torquemod.data import Recording, Rig

RIG = ir.OrbitRig()


def chain_cycle(channels: dict, fs_hz: float, nominal_hz: float,
                processing: dict | None = None) -> dict:
    """Phases [deg] of both methods, their windows [s], the modulation frequency [Hz] and
    the analysed span [s from the record's start] of one record as one cycle."""
    cfg = ProcessingConfig.for_modulation(nominal_hz, processing)
    rec = Recording(dict(channels), fs_hz)
    rig = Rig(RIG.wheel_radius_m, RIG.platform_radius_m)
    cs = chain.process_cycle(rec, rig, cfg, where="benchmark", nominal_hz=nominal_hz,
                             normal_load_n=RIG.normal_load_n)
    out = {"f": cs.modulation_hz,
           "span": (cs.t0_s, cs.t0_s + (cs.torque_resampled.size - 1) / cs.fs_hz)}
    for method in ("paper", "sinefit"):
        c = cfg.with_phase_method(method)
        ph, _, win = chain.cycle_phase(cs, c, center_index=(cs.torque_filtered.size - 1) / 2)
        out[method] = ph
        out[method + "_window"] = (cs.t0_s + win[0], cs.t0_s + win[1])
    return out


def steady(frequencies, utilisations) -> None:
    print("1. steady speed: |chain - periodic orbit| [deg], |frequency error| [Hz]")
    print(f"{'f [Hz]':>7} {'util':>5} {'paper':>9} {'sinefit':>9} {'freq':>9}")
    _, t_peak = ir.peak(RIG)
    worst = {}
    for f_nom in frequencies:
        for u in utilisations:
            f = f_nom * 1.0012
            run = ir.Run(RIG, u * t_peak, f, modulation_phase_rad=1.1, run_in_s=6.0,
                         duration_s=max(RIG.revolution_s, 7.0 / f_nom))
            on = ir.simulate(run)
            off = {k: np.zeros_like(v) for k, v in on.items()}
            ref = ir.record_phase_deg(on, off, run.fs_hz, f)
            got = chain_cycle(on, run.fs_hz, f_nom)
            e = (abs(got["paper"] - ref), abs(got["sinefit"] - ref), abs(got["f"] - f))
            worst[f_nom] = np.maximum(worst.get(f_nom, 0.0), e)
            print(f"{f_nom:7.1f} {u:5.2f} {e[0]:9.5f} {e[1]:9.5f} {e[2]:9.1e}", flush=True)
    for f_nom, e in worst.items():
        print(f"  worst at {f_nom} Hz: paper {e[0]:.5f} deg, sine fit {e[1]:.5f} deg, "
              f"frequency {e[2]:.1e} Hz")


#: white noise per sample at the independent rig's 2 kHz with the densities of
#: torquemod.testing.SyntheticSpec's defaults at 16.67 kHz (torque 0.5 N m, wheel 2e-3 rad/s,
#: platform 1e-3 rad/s): sigma * sqrt(2000/16670)
NOISE = {"torque_nm": 0.173, "wheel_speed_rad_s": 6.9e-4, "platform_speed_rad_s": 3.5e-4}


def _wobble_run(u: float, f_nom: float, seed: int, rms: float) -> ir.Run:
    rng = np.random.default_rng(seed)
    a = rms * math.sqrt(2.0 / 3.0)
    wob = ir.Wobble(
        lines=tuple((a, float(rng.uniform(0.2, 0.6)), float(rng.uniform(0, 2 * np.pi)))
                    for _ in range(3)),
        orders=((rms / 3, 1, float(rng.uniform(0, 2 * np.pi))),
                (rms / 6, 2, float(rng.uniform(0, 2 * np.pi)))))
    f = f_nom * (1 + float(rng.uniform(-1e-3, 1e-3)))
    _, t_peak = ir.peak(RIG)
    return ir.Run(RIG, u * t_peak, f, wobble=wob,
                  modulation_phase_rad=float(rng.uniform(0, 2 * np.pi)),
                  duration_s=max(RIG.revolution_s, 7.0 / f_nom))


def wobble(rms_values, seeds, utilisations, frequencies, n_noise: int) -> None:
    print("\n2. slow speed wobble: error [deg] against the defined phase over the span the "
          "chain analyses (defaults), the paper's own three middle periods "
          "(phase.paper_window = 'middle') and the full slow band (slow.quiet_max_hz = "
          "slow.max_hz, the chain before) for scale; noise: standard deviation [deg] over "
          f"{n_noise} copies with white noise (NOISE)")
    print(f"{'f Hz':>4} {'rms %':>5} {'seed':>4} {'util':>4} {'sinefit':>8} {'paper':>8}"
          f" {'pap mid':>8} {'sf wide':>8} {'pap wide':>8} {'freq Hz':>9} | {'sd sf':>6}"
          f" {'sd pap':>6}")
    rows = []
    rng = np.random.default_rng(0)
    for f_nom in frequencies:
        wide = {"slow": {"quiet_max_hz": 0.6 * f_nom}}
        middle = {"phase": {"paper_window": "middle"}}
        for rms in rms_values:
            for seed in seeds:
                for u in utilisations:
                    run = _wobble_run(u, f_nom, seed, rms)
                    f = run.modulation_hz
                    on, off = ir.simulate(run), ir.simulate(run, modulation=False)
                    got = chain_cycle(on, run.fs_hz, f_nom)
                    ref = ir.record_phase_deg(on, off, run.fs_hz, f, span_s=got["span"])
                    mid = chain_cycle(on, run.fs_hz, f_nom, middle)
                    wid = chain_cycle(on, run.fs_hz, f_nom, wide)
                    noisy = [chain_cycle({k: v + NOISE[k] * rng.standard_normal(v.size)
                                          if k in NOISE else v for k, v in on.items()},
                                         run.fs_hz, f_nom) for _ in range(n_noise)]
                    sd = [float(np.std([x[m] for x in noisy], ddof=1)) if n_noise > 1
                          else float("nan") for m in ("sinefit", "paper")]
                    e = (got["sinefit"] - ref, got["paper"] - ref, mid["paper"] - ref,
                         wid["sinefit"] - ref, wid["paper"] - ref, got["f"] - f)
                    rows.append((f_nom, u, *e, *sd))
                    print(f"{f_nom:4.0f} {100 * rms:5.2f} {seed:4d} {u:4.2f} {e[0]:+8.4f} "
                          f"{e[1]:+8.4f} {e[2]:+8.4f} {e[3]:+8.4f} {e[4]:+8.4f} {e[5]:+9.1e} | "
                          f"{sd[0]:6.4f} {sd[1]:6.4f}", flush=True)
    r = np.array(rows)
    print("\nmax |error| [deg] over seeds and wobble levels (noise: largest sd [deg]); "
          "targets: sine fit 0.1 (0.3 checked), paper 0.3 (0.5 checked), frequency 5e-4 Hz")
    print(f"{'f Hz':>4} {'util %':>6} {'sinefit':>8} {'paper':>8} {'pap mid':>8} {'sf wide':>8}"
          f" {'pap wide':>8} {'freq Hz':>8} {'sd sf':>6} {'sd pap':>6} {'n':>3}")
    for f_nom in frequencies:
        for u in utilisations:
            s = np.abs(r[(r[:, 0] == f_nom) & (r[:, 1] == u)])
            print(f"{f_nom:4.0f} {100 * u:6.0f} " + " ".join(f"{x:8.4f}" for x in
                  s[:, 2:7].max(axis=0)) + f" {s[:, 7].max():8.1e} {s[:, 8].max():6.4f} "
                  f"{s[:, 9].max():6.4f} {len(s):3d}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--noise-copies", type=int, default=3)
    ap.add_argument("--frequencies", type=float, nargs="+", default=[1.0, 2.0, 4.0])
    ap.add_argument("--rms", type=float, nargs="+", default=[0.002, 0.003])
    ap.add_argument("--skip-steady", action="store_true")
    args = ap.parse_args()
    t0 = time.perf_counter()
    if not args.skip_steady:
        steady((0.5, 1.0, 2.0, 4.0, 8.0), (0.3, 0.6, 0.8, 0.9))
    wobble(args.rms, range(1, args.seeds + 1), (0.6, 0.7, 0.8, 0.86, 0.9), args.frequencies,
           args.noise_copies)
    print(f"\n{time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
