"""Throughput of the processing chain.

1. The per-cycle chain on in-memory data: samples per second on one core (7 channels per
   sample counted as one sample of the recording) and its ratio to one memory pass
   (``np.sum``) over the same arrays.
2. End to end: ``torquemod process`` on an 18-recording CSV experiment (6 steps x 3 cycles,
   16 670 Hz, 7 columns), split into read time and compute time, against a plain script that
   reads with ``np.loadtxt`` and runs the same kind of scipy chain.

    python benchmarks/throughput.py [--workdir DIR]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from torquemod import chain
from torquemod.config import ProcessingConfig
from torquemod.data import CHANNELS, Rig
from torquemod.testing import SyntheticSpec, synthetic_recording, write_synthetic_experiment


def best_of(fn, repeat: int = 5) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def chain_throughput() -> None:
    rig, cfg = Rig(0.0675, 2.0), ProcessingConfig()
    rec = synthetic_recording(SyntheticSpec(seed=3))
    n = rec.n_samples
    data = np.vstack([rec.channels[k] for k in CHANNELS])

    def run(c=cfg) -> None:
        sig = chain.process_cycle(rec, rig, c, where="bench")
        chain.cycle_phase(sig, c, center_index=sig.torque_filtered.size / 2)

    t_chain = best_of(run)
    t_sine = best_of(lambda: run(cfg.with_phase_method("sinefit")))
    t_sum = best_of(lambda: np.sum(data), repeat=20)
    print(f"chain, one cycle of {n} samples x {len(CHANNELS)} channels (+ time):")
    print(f"  paper   : {t_chain * 1e3:7.2f} ms  -> {n / t_chain / 1e6:6.2f} M samples/s per core"
          f"  ({n * len(CHANNELS) / t_chain / 1e6:6.1f} M values/s)")
    print(f"  sinefit : {t_sine * 1e3:7.2f} ms  -> {n / t_sine / 1e6:6.2f} M samples/s per core")
    print(f"  np.sum over the same {data.size} values: {t_sum * 1e3:.3f} ms; chain / memory pass"
          f" = {t_chain / t_sum:.0f}x")


BASELINE = r'''
import sys, glob, numpy as np
from scipy import signal
for path in sorted(glob.glob(sys.argv[1] + "/*.csv")):
    d = np.loadtxt(path, delimiter=",", skiprows=1)
    t, tq, wh = d[:, 0], d[:, 1], d[:, 2]
    fs = 1 / np.median(np.diff(t))
    tq_r = signal.resample_poly(tq - tq.mean(), 2, 625)
    wh_r = signal.resample_poly(wh - wh.mean(), 2, 625)
    fr = fs * 2 / 625
    f = np.fft.rfftfreq(tq_r.size, 1 / fr)
    band = (f > 1.5) & (f < 2.5)
    fm = f[band][np.argmax(np.abs(np.fft.rfft(tq_r))[band])]
    for f0 in (wh.mean() / 2 / np.pi, wh.mean() / np.pi):
        b, a = signal.iirnotch(f0, 3, fs=fr)
        wh_r = signal.filtfilt(b, a, wh_r)
    b, a = signal.butter(2, [fm - 0.18, fm + 0.18], "bandpass", fs=fr)
    tq_f, wh_f = signal.filtfilt(b, a, tq_r), signal.filtfilt(b, a, wh_r)
    pt, _ = signal.find_peaks(tq_f)
    pw, _ = signal.find_peaks(wh_f)
'''


def _run_process(manifest: Path, out: Path, *extra: str) -> tuple[float, str]:
    exe = Path(sys.executable).with_name("torquemod")
    cmd = [str(exe), "process", str(manifest), "--out", str(out), "--force", "--quiet", *extra]
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True, check=True)
    return time.perf_counter() - t0, proc.stdout.strip().splitlines()[-1]


def end_to_end(workdir: Path) -> None:
    exp = workdir / "experiment"
    if not (exp / "experiment.toml").exists():
        print("writing the 18-recording CSV experiment ...", flush=True)
        write_synthetic_experiment(exp, n_steps=6, n_cycles=3)
    exp_h5 = workdir / "experiment_h5"
    if not (exp_h5 / "experiment.toml").exists():
        write_synthetic_experiment(exp_h5, n_steps=6, n_cycles=3, fmt="hdf5")
    size = sum(p.stat().st_size for p in exp.glob("*.csv"))
    t_import = best_of(lambda: subprocess.run(
        [sys.executable, "-c", "import torquemod.pipeline"], check=True), repeat=3)
    t_proc, tail = _run_process(exp / "experiment.toml", workdir / "results", "--no-fit")
    t_full, _ = _run_process(exp / "experiment.toml", workdir / "results_full")
    t_h5, tail_h5 = _run_process(exp_h5 / "experiment.toml", workdir / "results_h5", "--no-fit")
    base = workdir / "baseline.py"
    base.write_text(BASELINE)
    t0 = time.perf_counter()
    subprocess.run([sys.executable, str(base), str(exp)], check=True)
    t_base = time.perf_counter() - t0
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-c", "import numpy, scipy.signal"], check=True)
    t_base_import = time.perf_counter() - t0
    print(f"end to end, 18 recordings (6 steps x 3 cycles, 16 670 Hz), CSV {size / 1e6:.0f} MB:")
    print(f"  interpreter + import torquemod.pipeline: {t_import:6.2f} s")
    print(f"  torquemod process --no-fit (CSV):  {t_proc:6.2f} s wall; {tail}")
    print(f"  torquemod process (CSV, with fit and report): {t_full:6.2f} s wall")
    print(f"  torquemod process --no-fit (HDF5): {t_h5:6.2f} s wall; {tail_h5}")
    print(f"  np.loadtxt + scipy script (CSV):   {t_base:6.2f} s wall "
          f"(of which interpreter + numpy/scipy import {t_base_import:.2f} s)")
    print(f"  speed-up over the script: CSV {t_base / t_proc:.2f}x, HDF5 {t_base / t_h5:.2f}x; "
          f"excluding start-up: CSV {(t_base - t_base_import) / (t_proc - t_import):.2f}x")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--workdir", default=None, help="keep the experiment here between runs")
    args = ap.parse_args()
    print(f"cores visible: {os.cpu_count()}")
    chain_throughput()
    if args.workdir:
        Path(args.workdir).mkdir(parents=True, exist_ok=True)
        end_to_end(Path(args.workdir))
    else:
        with tempfile.TemporaryDirectory() as tmp:
            end_to_end(Path(tmp))


if __name__ == "__main__":
    main()
