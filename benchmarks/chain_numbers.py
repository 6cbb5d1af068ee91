"""The chain's numbers on a set of synthetic cycles, to compare two versions of the code
(prints figures, asserts nothing).

``dump`` runs ten synthetic cycles (two seeds with the default speed wobble, another seed,
no wobble, a three times stronger wobble, a ramp of speed and creepage, two revolutions,
slip, modulation at 2.3 Hz, a 1 Hz wobble) through steps 1-8 and the phase with both
decimators and both phase methods (the sine fit with each of its three inputs): 80
configurations, every number of the cycle (phase [deg], its standard error [deg], the
frequencies [Hz], creepage, its drift and CoA [-], the means, the ``extra`` statistics) to a
JSON file. ``compare`` prints, per quantity, how many values are identical and the largest
difference (absolute [deg] for the phase, relative otherwise). Run ``dump`` once per tree
(its ``src`` on PYTHONPATH), one BLAS thread as ``process`` runs:

    PYTHONPATH=<old>/src python benchmarks/chain_numbers.py dump old.json
    PYTHONPATH=src python benchmarks/chain_numbers.py dump new.json
    python benchmarks/chain_numbers.py compare old.json new.json

``spread`` measures how far the same code's numbers move with the BLAS kernels alone: it
runs ``dump`` in a fresh process per OpenBLAS kernel set (``OPENBLAS_CORETYPE``: the one
OpenBLAS picks for this CPU, Haswell's (what AMD Zen and older Intel CPUs get) and the
generic x86-64 one) and compares each with the first. This is the reproducibility of
today's numbers across the CPUs users run, the scale against which "the same numbers"
is judged:

    python benchmarks/chain_numbers.py spread
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import subprocess
import sys
import tempfile

import numpy as np

_WOBBLE = ((0.002, 0.27, 0.4), (0.0012, 0.55, 2.1), (0.0008, 0.9, 4.0))


def _specs() -> dict:
    from torquemod.testing import SyntheticSpec
    return {
        "seed3": SyntheticSpec(seed=3),  # the cycle of benchmarks/throughput.py
        "seed0": SyntheticSpec(seed=0),
        "seed11": SyntheticSpec(seed=11),
        "no_wobble": SyntheticSpec(seed=1, speed_wobble=(), speed_wobble_rev=()),
        "strong_wobble": SyntheticSpec(seed=2, speed_wobble=tuple((3 * a, f, p)
                                                                  for a, f, p in _WOBBLE)),
        "ramp": SyntheticSpec(seed=4, acceleration_m_s2=0.05, creepage_rate_per_s=0.0005),
        "two_revolutions": SyntheticSpec(seed=5, n_revolutions=2.0),
        "slip": SyntheticSpec(seed=6, slip_force_drop=0.3),
        "modulation_2p3_hz": SyntheticSpec(seed=7, modulation_hz=2.3),
        "wobble_1_hz": SyntheticSpec(seed=8, speed_wobble=((0.004, 1.0, 0.3),)),
    }


def dump(path: str) -> None:
    """Every number of the 80 configurations to ``path`` (JSON)."""
    from torquemod._util.blas import one_blas_thread
    from torquemod.io.config import ProcessingConfig
    from torquemod.io.experiment import Rig
    from torquemod.processing import chain
    from torquemod.testing import synthetic_recording
    rig, out = Rig(0.0675, 2.0), {}
    with one_blas_thread():
        for name, spec in _specs().items():
            rec = synthetic_recording(spec)
            for dec in ("two_stage", "polyphase"):
                for method, source in (("paper", "bandpassed"), ("sinefit", "bandpassed"),
                                       ("sinefit", "notched"), ("sinefit", "model")):
                    base = ProcessingConfig()
                    cfg = dataclasses.replace(
                        base, resample=dataclasses.replace(base.resample, method=dec),
                        phase=dataclasses.replace(base.phase, method=method,
                                                  sinefit_input=source))
                    sig = chain.process_cycle(rec, rig, cfg, where=name,
                                              nominal_hz=spec.modulation_hz)
                    phase, se, _ = chain.cycle_phase(sig, cfg,
                                                     center_index=sig.torque_filtered.size / 2)
                    row = {"phase": phase, "phase_se": se, "modulation_hz": sig.modulation_hz,
                           "torque_peak_hz": sig.torque_peak_hz,
                           "wheel_peak_hz": sig.wheel_peak_hz, "creepage": sig.creepage,
                           "creepage_drift": sig.creepage_drift, "coa": sig.coa,
                           "wheel_rotation_hz": sig.wheel_rotation_hz,
                           "torque_filtered_abs_sum": float(np.abs(sig.torque_filtered).sum())}
                    row.update({f"extra.{k}": float(v) for k, v in sig.extra.items()
                                if isinstance(v, (int, float)) and not isinstance(v, bool)})
                    row.update({f"mean.{k}": float(v) for k, v in sig.means.items()})
                    out[f"{name}/{dec}/{method}/{source}"] = row
    with open(path, "w") as fh:
        json.dump(out, fh, indent=0)
    print(f"{len(out)} configurations -> {path}")


def compare(path_a: str, path_b: str) -> None:
    """Identical values and the largest difference per quantity of two dumps."""
    with open(path_a) as fh:
        a = json.load(fh)
    with open(path_b) as fh:
        b = json.load(fh)
    worst: dict[str, tuple[float, str]] = {}
    same = total = beyond = 0
    for key, row in a.items():
        for q, va in row.items():
            vb = b[key][q]
            total += 1
            if va == vb or (va != va and vb != vb):
                same += 1
                d = 0.0
            else:
                d = abs(va - vb) if q == "phase" else abs(va - vb) / max(abs(va), 1e-300)
            if d >= worst.get(q, (-1.0, ""))[0]:
                worst[q] = (d, key)
            beyond += q == "phase" and d > 1e-9
    print(f"{same} of {total} values identical ({len(a)} configurations); "
          f"the phase more than 1e-9 deg apart in {beyond}")
    for q, (d, key) in sorted(worst.items()):
        unit = "deg" if q == "phase" else "rel"
        print(f"  {q:36s} largest difference {d:.3g} {unit}" + (f"  ({key})" if d else ""))


#: OpenBLAS kernel sets compared by ``spread``: this CPU's own (no override), Haswell's
#: (chosen on AMD Zen and pre-AVX-512 Intel CPUs) and the generic x86-64 one.
_CORETYPES = ("", "Haswell", "Prescott")


def spread() -> None:
    """The same code's numbers under each OpenBLAS kernel set, against this CPU's own."""
    with tempfile.TemporaryDirectory() as tmp:
        paths = []
        for core in _CORETYPES:
            env = dict(os.environ, OPENBLAS_NUM_THREADS="1")
            env.pop("OPENBLAS_CORETYPE", None)
            if core:
                env["OPENBLAS_CORETYPE"] = core
            path = os.path.join(tmp, f"{core or 'native'}.json")
            probe = ("import numpy, threadpoolctl; print(sorted({d['architecture'] for d in "
                     "threadpoolctl.threadpool_info() if d['internal_api'] == 'openblas'}))")
            arch = subprocess.run([sys.executable, "-c", probe], env=env, check=True,
                                  capture_output=True, text=True).stdout.strip()
            subprocess.run([sys.executable, __file__, "dump", path], env=env, check=True,
                           capture_output=True)
            paths.append(path)
            print(f"OPENBLAS_CORETYPE={core or '(unset)'}: OpenBLAS kernels {arch}")
        for core, path in zip(_CORETYPES[1:], paths[1:], strict=True):
            print(f"\n{core} against this CPU's own kernels:")
            compare(paths[0], path)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="command", required=True)
    sub.add_parser("dump").add_argument("out")
    c = sub.add_parser("compare")
    c.add_argument("a")
    c.add_argument("b")
    sub.add_parser("spread")
    args = ap.parse_args()
    if args.command == "dump":
        dump(args.out)
    elif args.command == "spread":
        spread()
    else:
        compare(args.a, args.b)


if __name__ == "__main__":
    main()
