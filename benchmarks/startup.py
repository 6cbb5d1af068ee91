"""Start-up of the ``torquemod`` command, against a bare ``python -c pass`` in the same run.

Each case is a fresh process, timed from its start (``subprocess.Popen``) until

* ``python -c pass``, ``torquemod --help``: it exits;
* ``torquemod process EXP --out DIR``: its first stage line on stderr (the experiment: one
  synthetic cycle, written once before the timing);
* ``torquemod simulate --out DIR``: its first stage line on stderr;

(the process and simulate runs are then stopped: what is timed is the wait before the first
sign of life, not the work). The kernel caches are warmed first by one whole ``process`` and
one whole ``simulate`` run. Cases are interleaved and repeated; the median of each is printed
with its ratio to ``python -c pass`` measured in the same rounds, and the machine's load.

    python benchmarks/startup.py [--repeat 7] [--src OTHER_CHECKOUT/src]

``python -X importtime -m torquemod.cli --help`` shows where the import time goes.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def _time_to(cmd: list[str], env: dict, first_line: bool) -> float:
    """Seconds from start until exit, or until the first stderr line (then stopped)."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env)
    try:
        if first_line:
            line = proc.stderr.readline()
            t = time.perf_counter() - t0
            if not line:
                raise SystemExit(f"{' '.join(cmd)} printed no stage line")
        else:
            proc.wait()
            t = time.perf_counter() - t0
            if proc.returncode != 0:
                raise SystemExit(f"{' '.join(cmd)} failed: {proc.stderr.read().decode()}")
    finally:
        if proc.poll() is None:
            proc.terminate()
            proc.wait()
        proc.stderr.close()
    return t


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--src", default=None,
                    help="the torquemod sources to time (default: this checkout's src)")
    args = ap.parse_args()
    src = args.src or str(Path(__file__).resolve().parents[1] / "src")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([src, os.environ.get("PYTHONPATH", "")])}
    py = sys.executable
    tm = [py, "-m", "torquemod.cli"]
    with tempfile.TemporaryDirectory() as tmp:
        exp = Path(tmp) / "exp"
        subprocess.run([py, "-c", "import sys; from torquemod.testing import "
                        "write_synthetic_experiment as w; w(sys.argv[1], n_steps=1, "
                        "n_cycles=1, fmt='hdf5')", str(exp)], env=env, check=True)
        # warm the kernel caches (and the OS file cache) with one whole run of each
        subprocess.run([*tm, "process", str(exp / "experiment.toml"), "--out",
                        f"{tmp}/res", "--force", "--quiet", "--no-fit"], env=env, check=True,
                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        subprocess.run([*tm, "simulate", "--out", f"{tmp}/sim", "--force", "--quiet"],
                       env=env, check=True, stdout=subprocess.DEVNULL,
                       stderr=subprocess.DEVNULL)
        cases = {
            "python -c pass": ([py, "-c", "pass"], False),
            "torquemod --help": ([*tm, "--help"], False),
            "process: first stage line": ([*tm, "process", str(exp / "experiment.toml"),
                                           "--out", f"{tmp}/res2", "--force"], True),
            "simulate: first stage line": ([*tm, "simulate", "--out", f"{tmp}/sim2",
                                            "--force"], True),
        }
        times: dict[str, list[float]] = {k: [] for k in cases}
        load0 = os.getloadavg()[0]
        for _ in range(args.repeat):
            for name, (cmd, first) in cases.items():
                times[name].append(_time_to(cmd, env, first))
    base = statistics.median(times["python -c pass"])
    print(f"start-up of torquemod ({src}); load {load0:.2f} -> {os.getloadavg()[0]:.2f}, "
          f"{os.cpu_count()} CPUs, median of {args.repeat}")
    print(f"{'case':>28s} {'median s':>9s} {'min s':>7s} {'x python -c pass':>17s} "
          f"{'minus it, s':>12s}")
    for name, ts in times.items():
        med = statistics.median(ts)
        print(f"{name:>28s} {med:9.3f} {min(ts):7.3f} {med / base:17.1f} {med - base:12.3f}")


if __name__ == "__main__":
    main()
