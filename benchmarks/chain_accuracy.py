"""The chain's phase and modulation frequency against an independent rig (prints figures,
asserts nothing).

The records come from ``tests/independent_rig.py`` (the rig's equations written apart from
torquemod, integrated by scipy's DOP853; noise-free, 2 kHz). Each record is one cycle of
``torquemod.processing.chain`` with ``ProcessingConfig.for_modulation`` of its nominal frequency
(what
a manifest that gives only the frequency gets).

1. Steady speed: |chain - periodic orbit| [deg] per modulation frequency (0.5-8 Hz, at
   least 7 periods per record) and utilisation (30-90 % of the creep curve's peak).
2. A slow speed wobble (three lines at 0.2-0.6 Hz, ``--rms`` of the set speed, plus a third
   and a sixth of it once and twice per revolution) at 60-90 %: the error of each method
   against the phase docs/processing.md defines for a moving operating point (over the span
   the chain analyses), the paper's also against the same definition over its own three
   middle periods, and the modulation frequency's error; with, for scale, how far the
   definition over the span moves from the whole record and from the middle periods.

    python benchmarks/chain_accuracy.py [--seeds 3] [--rms 0.002 0.003]
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
from torquemod.io.config import ProcessingConfig
from torquemod.io.experiment import Recording, Rig
from torquemod.processing import chain

RIG = ir.OrbitRig()


#: docs/processing.md, "The phase of a moving operating point": the configuration that
#: estimates it (at 2 Hz; for_modulation scales the slow band with f)
MOVING = {"slow": {"max_hz": 0.8}, "phase": {"sinefit_input": "model"}}


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


def wobble(rms_values, seeds, utilisations) -> None:
    print("\n2. slow speed wobble, 2 Hz: error [deg] against the defined phase over the span,"
          " with the defaults and (m) with the moving-point configuration; paper_mid against"
          " the definition over its own three middle periods")
    print(f"{'rms %':>6} {'seed':>4} {'util':>5} {'sinefit':>8} {'sf (m)':>8} {'paper':>8}"
          f" {'pap (m)':>8} {'paper_mid':>9} {'freq Hz':>9} | {'span-rec':>8} {'mid-span':>8}")
    _, t_peak = ir.peak(RIG)
    rows = []
    for rms in rms_values:
        for seed in seeds:
            rng = np.random.default_rng(seed)
            for u in utilisations:
                a = rms * math.sqrt(2.0 / 3.0)
                wob = ir.Wobble(
                    lines=tuple((a, float(rng.uniform(0.2, 0.6)),
                                 float(rng.uniform(0, 2 * np.pi))) for _ in range(3)),
                    orders=((rms / 3, 1, float(rng.uniform(0, 2 * np.pi))),
                            (rms / 6, 2, float(rng.uniform(0, 2 * np.pi)))))
                f = 2.0 * (1 + float(rng.uniform(-1e-3, 1e-3)))
                run = ir.Run(RIG, u * t_peak, f, wobble=wob,
                             modulation_phase_rad=float(rng.uniform(0, 2 * np.pi)))
                on, off = ir.simulate(run), ir.simulate(run, modulation=False)
                got = chain_cycle(on, run.fs_hz, 2.0)
                mov = chain_cycle(on, run.fs_hz, 2.0, MOVING)
                ref = ir.record_phase_deg(on, off, run.fs_hz, f, span_s=got["span"])
                whole = ir.record_phase_deg(on, off, run.fs_hz, f)
                lo, hi = got["paper_window"]
                mid = ir.record_phase_deg(on, off, run.fs_hz, f, span_s=(lo - 0.01, hi + 0.01),
                                          middle_periods=3)
                e = (got["sinefit"] - ref, mov["sinefit"] - ref, got["paper"] - ref,
                     mov["paper"] - ref, got["paper"] - mid, got["f"] - f)
                rows.append((rms, u, *e))
                print(f"{100 * rms:6.2f} {seed:4d} {u:5.2f} {e[0]:+8.4f} {e[1]:+8.4f} "
                      f"{e[2]:+8.4f} {e[3]:+8.4f} {e[4]:+9.4f} {e[5]:+9.1e} | "
                      f"{ref - whole:+8.3f} {mid - ref:+8.3f}", flush=True)
    r = np.array(rows)
    for u in utilisations:
        s = np.abs(r[r[:, 1] == u])
        print(f"  {100 * u:.0f} %: max |error| sine fit {s[:, 2].max():.4f} deg "
              f"({s[:, 3].max():.4f} moving config), paper {s[:, 4].max():.4f} deg "
              f"({s[:, 5].max():.4f}; own window {s[:, 6].max():.4f}), frequency "
              f"{s[:, 7].max():.1e} Hz over {len(s)} records")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--rms", type=float, nargs="+", default=[0.002, 0.003])
    ap.add_argument("--skip-steady", action="store_true")
    args = ap.parse_args()
    t0 = time.perf_counter()
    if not args.skip_steady:
        steady((0.5, 1.0, 2.0, 4.0, 8.0), (0.3, 0.6, 0.8, 0.9))
    wobble(args.rms, range(1, args.seeds + 1), (0.6, 0.7, 0.8, 0.9))
    print(f"\n{time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
