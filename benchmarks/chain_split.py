"""Where the chain's time goes after the decimation (prints figures, asserts nothing).

The benchmark's cycle of ``throughput.py`` (107 733 samples x 6 channels at 16 670 Hz,
resampled to 53.344 Hz) through steps 1-8 and the phase ``--cycles`` times on one BLAS
thread, with CPU time (``time.process_time``) summed around

1. each call that ``process_cycle`` and ``cycle_phase`` make (the steps), and
2. each compiled kernel and library routine inside them (numba kernels, LAPACK through
   scipy, numpy's FFT, the modulation's sines and cosines): the compute, the rest of the
   time being Python and numpy's per-call work ("glue").

Per cycle [ms]; a name a tree does not have is skipped, so the script also runs on older
trees (``PYTHONPATH=<tree>/src``) for before/after splits. The wrappers add ~1 us a call.

    python benchmarks/chain_split.py [--cycles 300]
"""

from __future__ import annotations

import argparse
import collections
import importlib
import time

_STEPS = [  # (module, attribute, label): the calls of the chain's steps
    ("torquemod.processing.chain", "needs_wide_band", "slow-band decision"),
    ("torquemod.processing.chain", "_slow_and_orders", "slow basis, tracked orders"),
    ("torquemod.processing.chain", "_modulation_peaks", "step 1: spectral peaks (2 passes)"),
    ("torquemod.processing.chain", "fit_speed_model", "speed model fit"),
    ("torquemod.processing.chain", "padded_and_filtered", "steps 3-5: padding, filters"),
    ("torquemod.processing.chain", "chain_filtered", "steps 3-5: padding, filters"),
    ("torquemod.processing.chain", "creepage_and_drift", "step 8: creepage fit"),
    ("torquemod.processing.chain", "sinefit_phase", "sine fit (standard error)"),
    ("torquemod.processing.chain", "peak_valley_phase", "peak/valley phase"),
]
_METHODS = [  # (module, class, method, label)
    ("torquemod.processing.speedmodel", "_SlowOrdersRemoval", "__init__",
     "step 1: basis of slow part and orders"),
    ("torquemod.processing.speedmodel", "_SlowOrdersRemoval", "at", "step 1: removal at f"),
    ("torquemod.processing.speedmodel", "_SlowOrdersRemoval", "refine_many",
     "step 1: refinement"),
    ("torquemod.processing.speedmodel", "_SlowOrdersRemoval", "search",
     "step 1: peaks (2 passes), removal, refinement"),
    ("torquemod.processing.speedmodel", "SpeedModel", "noise_depletion", "noise statistic"),
]
_KERNELS = [  # (module, attribute, label): compiled kernels and library routines
    ("torquemod.processing.trackedorders", "_tracked_orders_compiled", "tracked orders"),
    ("torquemod.processing.trackedorders", "_tracked_orders_fwl", "tracked orders (FWL)"),
    ("torquemod.processing.trackedorders", "_both_orders_fwl", "tracked orders (FWL)"),
    ("torquemod.dsp.blockbasis", "_extended_basis_t", "step 1 basis (block)"),
    ("torquemod.dsp.blockbasis", "_extended_basis_and_removal",
     "step 1 basis (block) and removal at the start"),
    ("torquemod.dsp.lstsq", "fit_with_parts", "speed model fit"),
    ("torquemod.dsp.jointfit", "fit_tone_model", "speed model fit"),
    ("torquemod.dsp.projection", "_refine", "step 1 refinement"),
    ("torquemod.dsp.tonesearch", "_refine", "step 1 refinement"),
    ("torquemod.dsp.modsearch", "_search_kernel", "step 1 peaks, removal, refinement"),
    ("torquemod.processing.speedmodel.projection", "orthonormal_basis_t",
     "orthonormal bases (LAPACK)"),
    ("torquemod.dsp.spectrum", "_peaks_of_spectra", "peaks: bins, Brent"),
    ("torquemod.dsp.spectrum", "_peaks_of_records",
     "peaks: detrending, bins (Goertzel), Brent"),
    ("torquemod.dsp.spectrum", "_detrended_windowed", "peaks: detrending"),
    ("numpy.fft", "rfft", "numpy FFT"),
    ("torquemod.dsp.padfilter", "_pad_and_filter", "steps 3-5"),
    ("torquemod.dsp.padfilter", "_chain_filtered_kernel", "steps 3-5 (designs, settling)"),
    ("torquemod.processing.speedmodel", "modulation_columns", "modulation columns (libm)"),
    ("torquemod.processing.creepage", "_creepage_fit", "creepage fit"),
    ("torquemod.dsp.phase", "_sine_fit", "sine fit"),
    ("torquemod.dsp.phase", "_sine_fit_records", "sine fit (with its design)"),
    ("torquemod.dsp.lstsq", "_factor_of", "LstsqFactor.of"),
    ("torquemod.dsp.lstsq", "_solve", "LstsqFactor.solve"),
    ("torquemod.dsp.projection", "_removal_at", "step 1 removal"),
    ("torquemod.dsp.projection", "_removal_at_tone", "step 1 removal (and its columns)"),
    ("torquemod.dsp.projection", "_powers_in_span", "noise statistic"),
    ("torquemod.dsp.projection", "_cholesky_qr2_t", "noise statistic (CholeskyQR2)"),
    ("torquemod.dsp.basis", "_wide_band_sums", "slow-band decision"),
    ("torquemod.dsp.basis", "_wide_band_test", "slow-band decision"),
    ("torquemod.dsp.filters", "_settling_kernel", "filters' settling"),
    ("torquemod.dsp.filters", "_butter_bandpass", "band-pass design"),
    ("torquemod.dsp.extrema", "_paired_extrema", "peak/valley extrema"),
]


def _timed(fn, acc, cnt, label, depth):
    def wrapper(*args, **kwargs):
        if depth[0]:  # inside another timed call of the same kind: counted there
            return fn(*args, **kwargs)
        depth[0] += 1
        t0 = time.process_time()
        try:
            return fn(*args, **kwargs)
        finally:
            acc[label] += time.process_time() - t0
            cnt[label] += 1
            depth[0] -= 1
    return wrapper


def _module(path: str):
    head, _, attr = path.rpartition(".")
    try:
        return importlib.import_module(path)
    except ImportError:
        return getattr(importlib.import_module(head), attr, None)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cycles", type=int, default=300)
    args = ap.parse_args()
    from _cycle import benchmark_cycle

    from torquemod._util.blas import one_blas_thread
    from torquemod.processing import chain

    _, _, _, cycle = benchmark_cycle()
    # one cycle before the wrappers: a kernel compiled afresh (no cache yet) would otherwise
    # see a wrapped kernel it calls as a Python function and fail to compile
    with one_blas_thread():
        cycle()
    steps, steps_n = collections.defaultdict(float), collections.defaultdict(int)
    kern, kern_n = collections.defaultdict(float), collections.defaultdict(int)
    d_steps, d_kern = [0], [0]
    chain.resampling.resample_rows = _timed(chain.resampling.resample_rows, steps, steps_n,
                                            "decimation", d_steps)
    for path, attr, label in _STEPS:
        mod = _module(path)
        if hasattr(mod, attr):
            setattr(mod, attr, _timed(getattr(mod, attr), steps, steps_n, label, d_steps))
    for path, cls, meth, label in _METHODS:
        owner = getattr(_module(path), cls, None)
        if owner is not None and hasattr(owner, meth):
            setattr(owner, meth, _timed(getattr(owner, meth), steps, steps_n, label, d_steps))
    for path, attr, label in _KERNELS:
        mod = _module(path)
        if mod is not None and hasattr(mod, attr):
            setattr(mod, attr, _timed(getattr(mod, attr), kern, kern_n, label, d_kern))

    total = [0.0]

    def run() -> None:
        t0 = time.process_time()
        cycle()
        total[0] += time.process_time() - t0

    with one_blas_thread():
        run()
        run()
        for d in (steps, steps_n, kern, kern_n):
            d.clear()
        total[0] = 0.0
        for _ in range(args.cycles):
            run()
    n = args.cycles
    dec = steps.pop("decimation")
    rest = total[0] - dec
    print(f"one cycle, {n} cycles, one BLAS thread, CPU per cycle [ms]: chain "
          f"{1e3 * total[0] / n:.3f} = decimation {1e3 * dec / n:.3f} + rest "
          f"{1e3 * rest / n:.3f}")
    print("the steps:")
    for label, v in sorted(steps.items(), key=lambda kv: -kv[1]):
        print(f"  {label:40s} {1e3 * v / n:7.3f}  ({steps_n[label] / n:.0f} a cycle)")
    print(f"  {'(the rest of process_cycle, cycle_phase)':40s} "
          f"{1e3 * (rest - sum(steps.values())) / n:7.3f}")
    print("compiled kernels and library routines within:")
    for label, v in sorted(kern.items(), key=lambda kv: -kv[1]):
        print(f"  {label:40s} {1e3 * v / n:7.3f}  ({kern_n[label] / n:.0f} a cycle)")
    compute = sum(kern.values())
    print(f"the rest {1e3 * rest / n:.3f} = compiled/library {1e3 * compute / n:.3f} + "
          f"Python and numpy's per-call work {1e3 * (rest - compute) / n:.3f}")


if __name__ == "__main__":
    main()
