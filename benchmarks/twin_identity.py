"""The V-Track twin's recordings and truth, this checkout against another, bit for bit.

Runs ``simulate_run`` for the first ``--points`` points of a sweep (default: the example
V-Track sweep, each point's configuration as its full mode gives it to the twin, with
``workers=1, large_signal=False`` as a sweep point calls it) and for the default experiment
(``torquemod simulate``'s default configuration, seed 0, default workers), once with this
checkout's ``src`` and once with ``--compare-src OTHER/src`` (each in a fresh process), and
compares every recording (each channel's and the sample times' bytes, rate, start time),
every manifest table and the whole truth (floats by their exact bits). With ``--sweep-call``
this checkout also runs the sweep's own call (``statistics=False``) and checks that it
gives the same recordings and the same truth but for the statistics it leaves out.

Prints one line per run and a closing line; exits 1 on any difference.

    python benchmarks/twin_identity.py --compare-src /work/main/src [--points 10]
                                       [--sweep examples/sweep_vtrack_conditions.toml]
                                       [--sweep-call]
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parents[1]
SWEEP = HERE / "examples" / "sweep_vtrack_conditions.toml"


def _exact(value):
    """``value`` with every float replaced by its exact hex text (signed zeros, NaN kept)."""
    if isinstance(value, float):
        return {"float": value.hex()}
    if isinstance(value, dict):
        return {str(k): _exact(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_exact(v) for v in value]
    return value


def _digest(run) -> dict:
    """Recordings by their bytes' SHA-256, and the tables and truth exactly."""
    recs = []
    for rec in run.recordings:
        ch = {k: hashlib.sha256(v.tobytes()).hexdigest() + f":{v.dtype}:{v.shape}"
              for k, v in rec.channels.items()}
        ch["time_s"] = hashlib.sha256(rec.time_s().tobytes()).hexdigest()
        recs.append({"fs_hz": float(rec.fs_hz).hex(), "t0_s": float(rec.t0_s).hex(),
                     "channels": ch})
    return {"recordings": recs, "entries": _exact(list(run.entries)),
            "tables": _exact([run.rig, run.test, run.extra]), "truth": _exact(run.truth)}


def _lean_truth(truth: dict) -> dict:
    """``truth`` as ``statistics=False`` leaves it: each step's simulated phase alone."""
    steps = [{**st, "simulated": {"phase_deg": st["simulated"]["phase_deg"]}}
             if "simulated" in st else st for st in truth["steps"]]
    return {**truth, "steps": steps}


def child(points: int, sweep: str, sweep_call: bool) -> None:
    """Print the digests of this process's torquemod (one JSON document on stdout)."""
    import dataclasses

    from torquemod.sweep.evaluate import _theory_steps, point_config, settle_time_s, tasks
    from torquemod.sweep.spec import load_sweep
    from torquemod.twins.vtrack.simulate import load_config, simulate_run
    out = {}
    for task in tasks(load_sweep(sweep))[:points]:
        config, t_peak = point_config(task)
        settle = settle_time_s(config, _theory_steps(config, t_peak))
        config = dataclasses.replace(config, procedure=dataclasses.replace(
            config.procedure, settle_s=settle))
        run = simulate_run(config, seed=task.seed, workers=1, large_signal=False)
        out[task.point_id] = _digest(run)
        if sweep_call:
            lean = simulate_run(config, seed=task.seed, workers=1, large_signal=False,
                                statistics=False)
            want = _digest(run)
            want["truth"] = _exact(_lean_truth(run.truth))
            out[task.point_id + " (the sweep's call)"] = {"same": _digest(lean) == want}
    out["default experiment"] = _digest(simulate_run(load_config(), seed=0))
    import torquemod
    json.dump({"package": torquemod.__file__, "runs": out}, sys.stdout)


def _run(src: str, args) -> dict:
    env = {**os.environ, "PYTHONPATH": src}
    cmd = [sys.executable, __file__, "--child", "--points", str(args.points), "--sweep",
           str(args.sweep)]
    done = subprocess.run(cmd + (["--sweep-call"] if args.sweep_call else []), env=env,
                          capture_output=True, text=True, check=False)
    if done.returncode:
        sys.exit(f"{src}: the child failed:\n{done.stderr}")
    doc = json.loads(done.stdout)
    print(f"ran {doc['package']}")
    return doc["runs"]


def _first_difference(a, b, path: str = "") -> str | None:
    if isinstance(a, dict) and isinstance(b, dict):
        if a.keys() != b.keys():
            return f"{path}: keys differ ({sorted(set(a) ^ set(b))})"
        for k in a:
            diff = _first_difference(a[k], b[k], f"{path}.{k}")
            if diff:
                return diff
        return None
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            return f"{path}: {len(a)} against {len(b)} items"
        for i, (u, v) in enumerate(zip(a, b, strict=True)):
            diff = _first_difference(u, v, f"{path}[{i}]")
            if diff:
                return diff
        return None
    return None if a == b else f"{path}: {a!r} against {b!r}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--compare-src", help="the other checkout's src folder")
    ap.add_argument("--points", type=int, default=10, help="sweep points to run")
    ap.add_argument("--sweep", default=str(SWEEP), help="the sweep file")
    ap.add_argument("--sweep-call", action="store_true",
                    help="also check this checkout's statistics=False against its full truth")
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        child(args.points, args.sweep, args.sweep_call)
        return
    if not args.compare_src:
        ap.error("--compare-src OTHER/src is required")
    mine = _run(str(HERE / "src"), args)
    other = _run(args.compare_src, argparse.Namespace(**{**vars(args), "sweep_call": False}))
    bad = 0
    for name, digest in mine.items():
        if name.endswith("(the sweep's call)"):
            ok = digest["same"]
            print(f"{name}: " + ("recordings and truth as the full call, statistics aside"
                                 if ok else "DIFFERS from the full call"))
            bad += not ok
            continue
        diff = _first_difference(digest, other.get(name))
        n = sum(len(r["channels"]) for r in digest["recordings"])
        print(f"{name}: {'identical' if diff is None else 'DIFFERS: ' + diff} "
              f"({len(digest['recordings'])} recordings, {n} arrays)")
        bad += diff is not None
    print(f"{len(mine) - bad} of {len(mine)} runs identical to {args.compare_src}"
          + ("" if bad else ": bit for bit"))
    sys.exit(1 if bad else 0)


if __name__ == "__main__":
    main()
