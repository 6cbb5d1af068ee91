"""Peak memory of ``torquemod process`` on one long recording.

Writes a synthetic HDF5 recording of ``--minutes`` minutes at 16 670 Hz (7 channels: time
base as attributes, 6 float64 datasets, one file spanning many platform revolutions, no
``cycle`` in the manifest), then processes it in a fresh Python process and reports

* the size of one copy of the recording (7 float64 channels, time included),
* peak RSS (``resource.getrusage``, max resident set) minus the RSS after the imports,
* the peak of numpy's allocations traced by ``tracemalloc`` (``--tracemalloc``; slower),

and both scaled to one recorded hour. The recording is generated one revolution at a time so
that the generator's own memory does not enter the figure.

    python benchmarks/memory.py [--minutes 15] [--workdir DIR] [--workers N]

``--reading HOURS...`` (issue 11) instead measures reading alone: for each length it writes
an HDF5 recording with a ``time_s`` column and the 6 channels (fast synthetic signals, written
in blocks), then in a fresh process per case reads it whole (``read_recording``) or streamed
(``torquemod.io.stream.iter_chunks``, summing every chunk so each value is touched), and
prints peak RSS above the post-import baseline and CPU time. Reading whole is skipped when
one copy would not fit in the machine's memory. ``--chain`` adds a third case: streamed
revolution by revolution (``RecordingStream.revolutions``) through the per-cycle chain.

    python benchmarks/memory.py --reading 0.1667 1 [--chain] [--workdir DIR] [--keep]

``--command MINUTES...`` measures the command itself: for each length it writes an HDF5
recording (one step, no ``cycle``: the file is split into revolutions while it is read;
``--dtype f4`` stores the samples as float32 to halve the disk it takes, the reader works in
float64 either way), runs ``torquemod process`` on it as a subprocess (fit and report
included) and prints the child's peak RSS (``os.wait4``'s ``ru_maxrss``), its CPU time and
the growth of the peak against the shortest length. The free disk is checked first; a length
that does not fit is skipped with a line saying so. One unmeasured run on a 1-min recording
first fills numba's kernel cache of the source tree measured.

    python benchmarks/memory.py --command 10 60 180 600 [--dtype f4] [--workdir DIR]
                                [--src OTHER_CHECKOUT/src] [--sample 0.01]

``--layout L1 L2 ...`` writes the recording in each of these ways (``benchmarks/_layouts.py``:
HDF5 contiguous, with a ``time_s`` dataset, h5py's automatic or resizable chunks, chunks of
2**20 or 2**22 samples, gzip with shuffle; MATLAB v7.3, TDMS, MDF4, Parquet, CSV), measures
each length in each, and says whether the results (``cycles.csv``, ``steps.csv``) are those of
the first layout. Each recording is written by a separate Python process: a child's
``ru_maxrss`` includes its parent's peak at the time it was started.

``--nan POLICY`` damages every recording with a few runs of NaN/inf samples
(:data:`NAN_RUNS`: at the start and the end of a channel, single samples, runs in the
platform speed; HDF5 layouts only) and runs ``torquemod process --nan-policy POLICY``
(``interpolate`` or ``drop-cycle``).

``--sample SECONDS`` also reads the child's ``VmRSS`` from ``/proc`` that often and prints
when the peak was reached and the largest resident size in each tenth of the run (the
kernels load at the start, the report is written at the end).

``--train HOURS...`` (issues 10 and 11) measures a train run through the on-board estimator
(``torquemod.ontrain.run.estimate_axle``, which reads through ``RunStream`` 30 s at a time):
an HDF5 run of the twin's layout (torque and wheel speed at 1 kHz, the reference speed and
position at 20 Hz on their own time vector) written in blocks, processed in a fresh process
streamed, and, for comparison, read whole first (the batch path before streaming).

    python benchmarks/memory.py --train 0.25 1 10 [--workdir DIR]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

FS_HZ = 16_670.0
N_CHANNELS = 7  # time + the 6 method channels
#: the rig's six channels (torquemod.io.experiment.CHANNELS also lists the train run's two)
RIG_CHANNELS = ("torque_nm", "wheel_speed_rad_s", "platform_speed_rad_s", "fx_n", "fy_n",
                "fz_n")


def _write_long_manifest(folder: Path, spec) -> None:
    """The manifest of one step recorded as ``long.h5`` at 2 Hz, with the rig of ``spec``
    (a :class:`torquemod.testing.SyntheticSpec`)."""
    from torquemod.io import write_manifest

    write_manifest(folder / "experiment.toml",
                   rig={"wheel_radius_m": spec.wheel_radius_m,
                        "platform_radius_m": spec.platform_radius_m},
                   test={"normal_load_n": spec.normal_load_n, "modulation_frequency_hz": 2.0,
                         "modulation_amplitude_nm": spec.modulation_amplitude_nm},
                   recordings=[{"step": 1, "dc_torque_nm": spec.dc_torque_nm,
                                "file": "long.h5"}])


def generate(folder: Path, minutes: float) -> dict:
    """One HDF5 file of ``minutes`` of synthetic data, written revolution by revolution."""
    import h5py
    import numpy as np

    from torquemod.io.experiment import CHANNEL_UNITS
    from torquemod.testing import SyntheticSpec, synthetic_recording

    folder.mkdir(parents=True, exist_ok=True)
    base = SyntheticSpec(fs_hz=FS_HZ)
    rev_s = 2 * np.pi / base.platform_speed_rad_s
    n_rev = max(1, int(minutes * 60 / rev_s))
    path = folder / "long.h5"
    with h5py.File(path, "w") as fh:
        fh.attrs["torquemod_layout"] = 1
        fh.attrs["sample_rate_hz"] = FS_HZ
        fh.attrs["t0_s"] = 0.0
        ds = {c: fh.create_dataset(c, shape=(0,), maxshape=(None,), dtype="f8",
                                   chunks=(1 << 16,)) for c in RIG_CHANNELS}
        for c in RIG_CHANNELS:
            ds[c].attrs["unit"] = CHANNEL_UNITS[c]
        n = 0
        for k in range(n_rev):
            rec = synthetic_recording(dataclasses.replace(
                base, n_revolutions=1.0, seed=k, modulation_phase_rad=0.37 * k))
            m = rec.n_samples
            for c in RIG_CHANNELS:
                ds[c].resize((n + m,))
                ds[c][n:n + m] = rec.channels[c]
            n += m
    _write_long_manifest(folder, base)
    return {"n_samples": n, "revolutions": n_rev, "duration_s": n / FS_HZ}


def _rss_peak_bytes() -> int:
    """Max resident set size of this process so far [bytes] (ru_maxrss is KiB on Linux)."""
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return peak if sys.platform == "darwin" else peak * 1024


def _rss_now_bytes() -> int:
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * resource.getpagesize()


def measure(folder: Path, workers: int, trace: bool, out_dir: Path) -> dict:
    """Process the experiment in this (fresh) process; memory figures in bytes."""
    import tracemalloc

    import numpy  # noqa: F401  (imports count as baseline)
    import pandas  # noqa: F401
    import scipy.signal  # noqa: F401

    from torquemod.api import run  # noqa: F401
    from torquemod.processing.pipeline import process_experiment
    from torquemod.results.folder import save

    base_now = _rss_now_bytes()
    base_peak = _rss_peak_bytes()
    if trace:
        tracemalloc.start()
    t0 = time.perf_counter()
    res = process_experiment(folder / "experiment.toml", workers=workers)
    save(res, None, out_dir, force=True)
    wall = time.perf_counter() - t0
    traced = tracemalloc.get_traced_memory()[1] if trace else None
    return {"baseline_rss": base_now, "baseline_peak_rss": base_peak,
            "peak_rss": _rss_peak_bytes(), "traced_peak": traced, "wall_s": wall,
            "n_cycles": len(res.cycles)}


def generate_long(folder: Path, minutes: float, dtype: str = "f8",
                  block_s: float = 60.0, layout: str = "chunk64k") -> dict:
    """One recording of ``minutes`` of continuous rig signals, written block by block: the
    platform and wheel at the default synthetic speeds with 1x/2x encoder eccentricity, a
    2 Hz torque modulation answered 20 deg later by the wheel speed, constant forces, white
    noise (levels of :class:`torquemod.testing.SyntheticSpec`). ``layout`` is how the file
    is written (``benchmarks/_layouts.py``; default: HDF5 with chunks of 65 536 samples);
    the samples are the same in every layout of the same ``dtype``."""
    import numpy as np

    from torquemod.io import write_manifest
    from torquemod.testing import SyntheticSpec

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import _layouts

    folder.mkdir(parents=True, exist_ok=True)
    sp = SyntheticSpec(fs_hz=FS_HZ)
    n_total = round(minutes * 60 * FS_HZ)
    name, extra = _layouts.write(layout, folder, n_total, FS_HZ, dtype,
                                 _layouts.rig_blocks(n_total, FS_HZ, block_s))
    write_manifest(folder / "experiment.toml",
                   rig={"wheel_radius_m": sp.wheel_radius_m,
                        "platform_radius_m": sp.platform_radius_m},
                   test={"normal_load_n": sp.normal_load_n, "modulation_frequency_hz": 2.0,
                         "modulation_amplitude_nm": sp.modulation_amplitude_nm},
                   recordings=[{"step": 1, "dc_torque_nm": sp.dc_torque_nm, "file": name}],
                   extra=extra or None)
    wp = sp.platform_speed_rad_s
    return {"n_samples": n_total, "revolutions": int(n_total / FS_HZ * wp / (2 * np.pi)),
            "duration_s": n_total / FS_HZ, "file": name}


#: The runs ``--nan`` writes: (channel, first row as a fraction of the file, rows, value); a
#: negative fraction counts from the end.
NAN_RUNS = (("torque_nm", 0.0, 200, float("nan")),  # the channel's start
            ("torque_nm", 0.5, 1, float("nan")),
            ("wheel_speed_rad_s", 0.7, 50, float("inf")),
            ("platform_speed_rad_s", 0.3, 500, float("nan")),  # cuts the revolutions
            ("platform_speed_rad_s", 0.61, 1, float("nan")),
            ("fx_n", 0.25, 3000, float("nan")),
            ("fz_n", -300, 300, float("nan")))  # the channel's end


def damage(path: Path) -> int:
    """Write :data:`NAN_RUNS` into an HDF5 recording of 1-D channels; NaN/inf samples."""
    import h5py
    import numpy as np

    total = 0
    with h5py.File(path, "r+") as fh:
        for c, where, rows, value in NAN_RUNS:
            n = fh[c].shape[0]
            a = n + int(where) if where < 0 else int(where * n)
            fh[c][a:a + rows] = np.full(min(rows, n - a), value)
            total += min(rows, n - a)
    return total


def _sample_rss(pid: int, t0: float, every_s: float, out: list) -> None:
    """Append (seconds since ``t0``, VmRSS [bytes]) of process ``pid`` every ``every_s``
    until it ends (Linux ``/proc``)."""
    path = f"/proc/{pid}/status"
    while True:
        try:
            with open(path) as fh:
                rss = next(int(x.split()[1]) * 1024 for x in fh if x.startswith("VmRSS"))
        except (OSError, StopIteration, ValueError):
            return
        out.append((time.perf_counter() - t0, rss))
        time.sleep(every_s)


def run_measured(cmd: list[str], env: dict | None = None, sample_s: float | None = None
                 ) -> dict:
    """Run ``cmd``; its peak RSS [bytes] (``os.wait4``: this child alone), CPU and wall [s];
    with ``sample_s``, also its resident size sampled from outside that often
    (``samples``: (s, bytes) pairs)."""
    import os
    import threading

    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env)
    samples: list = []
    sampler = None
    if sample_s:
        sampler = threading.Thread(target=_sample_rss, args=(proc.pid, t0, sample_s, samples),
                                   daemon=True)
        sampler.start()
    _, status, usage = os.wait4(proc.pid, 0)
    if sampler is not None:
        sampler.join()
    proc.returncode = os.waitstatus_to_exitcode(status)
    err = proc.stderr.read().decode(errors="replace")
    proc.stderr.close()
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed ({proc.returncode}):\n{err}")
    peak = usage.ru_maxrss if sys.platform == "darwin" else usage.ru_maxrss * 1024
    return {"peak_rss": peak, "cpu_s": usage.ru_utime + usage.ru_stime,
            "wall_s": time.perf_counter() - t0, "samples": samples}


def _timeline(samples: list, wall_s: float, parts: int = 10) -> str:
    """Where the sampled peak fell and the largest resident size in each tenth of the run
    [MiB]: a peak early is the loading, in the middle the streaming, late the report."""
    if not samples:
        return "no samples"
    t_pk, pk = max(samples, key=lambda x: x[1])
    tenths = [max((r for t, r in samples if k * wall_s / parts <= t < (k + 1) * wall_s / parts),
                  default=0) / 2**20 for k in range(parts)]
    return (f"sampled peak {pk / 2**20:.0f} MiB at {t_pk:.1f} of {wall_s:.1f} s; max by "
            f"tenth of the run: " + " ".join(f"{x:.0f}" for x in tenths))


def _compare_results(a: Path, b: Path) -> str:
    """Whether two results folders hold the same numbers: ``cycles.csv`` and ``steps.csv``
    byte for byte, else the largest relative difference of their numeric cells (plain
    Python: the measuring process stays small, see :func:`_generate_apart`)."""
    import csv
    import math

    worst = 0.0
    for name in ("cycles.csv", "steps.csv"):
        if (a / name).read_bytes() == (b / name).read_bytes():
            continue
        with open(a / name) as fa, open(b / name) as fb:
            x, y = list(csv.reader(fa)), list(csv.reader(fb))
        if len(x) != len(y) or x[:1] != y[:1]:
            return f"{name}: other columns or rows"
        for row_x, row_y in zip(x[1:], y[1:], strict=True):
            for u, v in zip(row_x, row_y, strict=True):
                try:
                    u, v = float(u), float(v)
                except ValueError:
                    if u != v:
                        return f"{name}: {u!r} against {v!r}"
                    continue
                if u != v and not (math.isnan(u) and math.isnan(v)):
                    worst = max(worst, abs(u - v) / max(abs(u), 1e-300))
    return "identical" if worst == 0 else f"differ (max rel {worst:.1e})"


def _generate_apart(folder: Path, minutes: float, dtype: str, layout: str,
                    nan: bool = False) -> dict:
    """:func:`generate_long` in a fresh Python process. A child's ``ru_maxrss`` includes
    the peak its parent had reached when it was started (Linux counts the address space
    that ``exec`` replaces, here the parent's), so the process that measures must not itself
    hold a generator's blocks: writing a 60-s block with gzip had lifted a 317 MiB run of
    ``torquemod process`` to 379 MiB."""
    out = subprocess.run([sys.executable, __file__, "--_long", str(folder), "--minutes",
                          str(minutes), "--dtype", dtype, "--layout", layout,
                          *(["--_damage"] if nan else [])],
                         check=True, capture_output=True, text=True).stdout
    return json.loads(out)


def command(minutes_list: list[float], workdir: str | None, dtype: str,
            src: str | None = None, sample_s: float | None = None,
            layouts: list[str] | None = None, nan: str | None = None,
            keep_results: str | None = None) -> None:
    """Peak RSS of ``torquemod process`` on recordings of these lengths and layouts (see
    module doc)."""
    import os
    import shutil

    layouts = layouts or ["chunk64k"]
    mib = 2**20
    itemsize = 4 if dtype == "f4" else 8
    tmp = Path(tempfile.mkdtemp(dir=workdir))
    print(f"torquemod process on one recording ({len(RIG_CHANNELS)} channels {dtype}, "
          f"{FS_HZ:.0f} Hz, one step split into revolutions while read); load "
          f"{os.getloadavg()[0]:.2f}"
          + (f"; {len(NAN_RUNS)} runs of NaN/inf, --nan-policy {nan}" if nan else ""))
    policy = ["--nan-policy", nan] if nan else []
    print(f"{'layout':>15s} {'length':>8s} {'file MiB':>9s} {'revs':>6s} "
          f"{'peak RSS MiB':>13s} {'vs first':>9s} {'CPU s':>8s} {'wall s':>8s} "
          f"{'x real time':>11s}  results vs {layouts[0]}")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        [src or str(Path(__file__).resolve().parents[1] / "src"),
         os.environ.get("PYTHONPATH", "")])}
    try:
        # numba's cache lives beside each source tree: a checkout whose kernels were never
        # compiled would charge the compiler's memory (hundreds of MiB) to the first length
        # only. One unmeasured run on a one-minute recording first fills the cache.
        warm = tmp / "exp_warm"
        _generate_apart(warm, 1.0, dtype, "chunk64k")
        w = run_measured([sys.executable, "-m", "torquemod.cli", "process",
                          str(warm / "experiment.toml"), "--out", str(tmp / "results"),
                          "--force", "--quiet"], env=env)
        shutil.rmtree(warm)
        print(f"  (kernel cache warmed first on a 1-min recording: {w['cpu_s']:.1f} CPU-s, "
              f"peak {w['peak_rss'] / mib:.0f} MiB; not counted)", flush=True)
        for layout in layouts:
            first = None
            for minutes in minutes_list:
                need = minutes * 60 * FS_HZ * len(RIG_CHANNELS) * itemsize
                free = shutil.disk_usage(tmp).free
                if need > 0.7 * free:
                    print(f"{layout:>15s} {minutes:6.0f}min {need / mib:9.0f} skipped: needs "
                          f"more than 70 % of the {free / 2**30:.0f} GiB free in {tmp}",
                          flush=True)
                    continue
                folder = tmp / f"exp_{minutes:g}"
                gen = _generate_apart(folder, minutes, dtype, layout, nan=bool(nan))
                size = (folder / gen["file"]).stat().st_size
                out = tmp / f"results_{layout}_{minutes:g}"
                m = run_measured([sys.executable, "-m", "torquemod.cli", "process",
                                  str(folder / "experiment.toml"), "--out", str(out),
                                  "--force", "--quiet", *policy], env=env,
                                 sample_s=sample_s)
                first = first or m["peak_rss"]
                ref = tmp / f"results_{layouts[0]}_{minutes:g}"
                same = "" if layout == layouts[0] else _compare_results(ref, out)
                print(f"{layout:>15s} {minutes:6.0f}min {size / mib:9.0f} "
                      f"{gen['revolutions']:6d} {m['peak_rss'] / mib:13.0f} "
                      f"{100 * (m['peak_rss'] / first - 1):8.1f}% {m['cpu_s']:8.1f} "
                      f"{m['wall_s']:8.1f} {gen['duration_s'] / m['cpu_s']:11.0f}  {same}",
                      flush=True)
                if sample_s:
                    print(f"{'':8s} {_timeline(m['samples'], m['wall_s'])}", flush=True)
                shutil.rmtree(folder)
                if keep_results:
                    shutil.copytree(out, Path(keep_results) / out.name, dirs_exist_ok=True)
                if layout != layouts[0]:
                    shutil.rmtree(out)
        print(f"  (this process's own peak: {_rss_peak_bytes() / mib:.0f} MiB, the floor of "
              "every figure above)")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


READ_CHANNELS = 7  # time_s and the 6 method channels


def generate_plain(path: Path, hours: float, block: int = 1 << 20) -> int:
    """An HDF5 recording of ``hours`` at FS_HZ: ``time_s`` and the 6 channels (a 2 Hz
    modulation on offsets, rotation tones and noise), written block by block [samples]."""
    import h5py
    import numpy as np

    from torquemod.io.experiment import CHANNEL_UNITS

    n = round(hours * 3600 * FS_HZ)
    rng = np.random.default_rng(1)
    level = {"torque_nm": 40.0, "wheel_speed_rad_s": 29.6, "platform_speed_rad_s": 0.74,
             "fx_n": 900.0, "fy_n": 150.0, "fz_n": 4200.0}
    with h5py.File(path, "w") as fh:
        fh.attrs["torquemod_layout"] = 1
        names = ["time_s", *RIG_CHANNELS]
        ds = {c: fh.create_dataset(c, shape=(n,), dtype="f8", chunks=(1 << 16,))
              for c in names}
        for c in RIG_CHANNELS:
            ds[c].attrs["unit"] = CHANNEL_UNITS[c]
        ds["time_s"].attrs["unit"] = "s"
        for a in range(0, n, block):
            b = min(n, a + block)
            t = np.arange(a, b) / FS_HZ
            ds["time_s"][a:b] = t
            for k, c in enumerate(RIG_CHANNELS):
                x = level[c] * (1 + 0.01 * np.sin(2 * np.pi * 2.0 * t + k)
                                + 0.002 * np.sin(2 * np.pi * 4.6 * t))
                x += 1e-3 * level[c] * rng.standard_normal(b - a)
                ds[c][a:b] = x
    return n


def measure_read(path: Path, mode: str) -> dict:
    """Read ``path`` whole or streamed in this (fresh) process; bytes and seconds."""
    import numpy as np  # noqa: F401  (imports count as baseline)

    from torquemod.io import read_recording
    from torquemod.io.stream import iter_chunks

    base_now = _rss_now_bytes()
    t0, c0 = time.perf_counter(), time.process_time()
    total = 0.0
    if mode == "whole":
        rec = read_recording(path)
        n = rec.n_samples
        total = sum(float(x.sum()) for x in rec.channels.values())
    elif mode == "revolutions":  # streamed, and the per-cycle chain on every revolution
        from torquemod.io.config import ProcessingConfig
        from torquemod.io.experiment import Rig
        from torquemod.io.stream import open_stream
        from torquemod.processing import chain

        cfg, rig, n = ProcessingConfig(), Rig(0.0675, 2.0), 0
        with open_stream(path) as stream:
            for k, seg, _ in stream.revolutions():
                sig = chain.process_cycle(seg, rig, cfg, where=f"revolution {k}",
                                          nominal_hz=2.0)
                total += chain.cycle_phase(sig, cfg,
                                           center_index=sig.torque_filtered.size / 2)[0]
                n += seg.n_samples
    else:
        n = 0
        for chunk in iter_chunks(path):
            n += chunk["torque_nm"].size
            total += sum(float(x.sum()) for x in chunk.values())
    return {"baseline_rss": base_now, "peak_rss": _rss_peak_bytes(), "n": n, "sum": total,
            "wall_s": time.perf_counter() - t0, "cpu_s": time.process_time() - c0}


def _in_fresh_process(*args: str) -> tuple[dict, int]:
    """This script run with ``args`` in a fresh Python process: the figures it prints (JSON)
    and its peak RSS above its post-import baseline [bytes]."""
    m = json.loads(subprocess.run([sys.executable, __file__, *args], check=True,
                                  capture_output=True, text=True).stdout)
    return m, m["peak_rss"] - m["baseline_rss"]


def reading(hours_list: list[float], workdir: str | None, keep: bool,
            chain: bool = False) -> None:
    import os

    mib = 2**20
    mem_total = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    print(f"reading an HDF5 recording ({READ_CHANNELS} float64 columns incl. time_s, "
          f"{FS_HZ:.0f} Hz) whole vs streamed; machine memory {mem_total / 2**30:.1f} GiB")
    print(f"{'length':>8s} {'file MiB':>9s} {'mode':>11s} {'peak RSS above baseline':>24s} "
          f"{'copies':>7s} {'wall s':>7s} {'CPU s':>7s}")
    tmp = tempfile.mkdtemp(dir=workdir)
    try:
        for hours in hours_list:
            path = Path(tmp) / f"long_{hours:g}h.h5"
            n = generate_plain(path, hours)
            one_copy = n * READ_CHANNELS * 8
            for mode in ("whole", "streamed", *(("revolutions",) if chain else ())):
                if mode == "whole" and 1.5 * one_copy > 0.8 * mem_total:
                    print(f"{hours:7.3g}h {path.stat().st_size / mib:9.0f} {mode:>11s} "
                          f"{'skipped: does not fit':>24s}")
                    continue
                m, used = _in_fresh_process("--_read", str(path), "--_mode", mode)
                print(f"{hours:7.3g}h {path.stat().st_size / mib:9.0f} {mode:>11s} "
                      f"{used / mib:20.0f} MiB {used / one_copy:7.3f} {m['wall_s']:7.1f} "
                      f"{m['cpu_s']:7.1f}", flush=True)
            if not keep:
                path.unlink()
    finally:
        if not keep:
            import shutil
            shutil.rmtree(tmp, ignore_errors=True)


TRAIN_FS_HZ, TRAIN_REF_HZ = 1000.0, 20.0
TRAIN_MANIFEST = """recording = [{{ file = "run.h5", axle = 1 }}]

[vehicle]
wheel_radius_m = 0.46
normal_load_n = 200000.0
inertia_kg_m2 = 380.0

[test]
modulation_frequency_hz = 5.0
modulation_amplitude_nm = 1200.0

[channels]
time = "time_s"
torque = "torque_nm"
wheel_speed = "wheel_speed_rad_s"
vehicle_speed = {{ name = "vehicle_speed_m_s", time = "reference_time_s" }}
position = {{ name = "position_m", time = "reference_time_s" }}
"""


def generate_train(folder: Path, hours: float, block_s: float = 600.0) -> int:
    """A train run of ``hours``: 20 m/s with a slow speed wobble, a DC torque that steps
    every 60 s, a 5 Hz modulation and a wheel-speed response lagging it by 30-60 degrees
    (more at higher torque), noise; written block by block [fast samples]."""
    import h5py
    import numpy as np

    folder.mkdir(parents=True, exist_ok=True)
    n = round(hours * 3600 * TRAIN_FS_HZ)
    n_ref = round(hours * 3600 * TRAIN_REF_HZ) + 1
    rng = np.random.default_rng(2)
    radius, f_mod = 0.46, 5.0

    def speed(t):
        return 20.0 + 0.8 * np.sin(2 * np.pi * t / 400.0)

    with h5py.File(folder / "run.h5", "w") as fh:
        ds = {c: fh.create_dataset(c, shape=(n,), dtype="f8", chunks=(1 << 16,))
              for c in ("time_s", "torque_nm", "wheel_speed_rad_s")}
        for a in range(0, n, round(block_s * TRAIN_FS_HZ)):
            b = min(n, a + round(block_s * TRAIN_FS_HZ))
            t = np.arange(a, b) / TRAIN_FS_HZ
            level = 0.2 + 0.15 * (np.floor(t / 60.0) % 4)  # share of the top torque
            lag = np.deg2rad(30.0 + 60.0 * level)
            ds["time_s"][a:b] = t
            ds["torque_nm"][a:b] = (20e3 * level + 1200.0 * np.sin(2 * np.pi * f_mod * t)
                                    + 30.0 * rng.standard_normal(b - a))
            ds["wheel_speed_rad_s"][a:b] = (speed(t) / radius * (1 + 2e-3 * level)
                                            + 0.004 * np.sin(2 * np.pi * f_mod * t - lag)
                                            + 5e-4 * rng.standard_normal(b - a))
        t_ref = np.arange(n_ref) / TRAIN_REF_HZ
        v = speed(t_ref) + 0.02 * rng.standard_normal(n_ref)
        x = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) / TRAIN_REF_HZ)])
        for name, arr in (("reference_time_s", t_ref), ("vehicle_speed_m_s", v),
                          ("position_m", x)):
            fh.create_dataset(name, data=arr)
    (folder / "run.toml").write_text(TRAIN_MANIFEST.format())
    return n


def measure_train(folder: Path, mode: str) -> dict:
    """The run's axle through the estimator in this (fresh) process: ``streamed``
    (estimate_axle) or ``whole`` (read_recording first, then the same estimator)."""
    import numpy as np
    import pandas  # noqa: F401  (imports count as baseline)

    from torquemod.io.recording import read_recording
    from torquemod.io.run import read_run
    from torquemod.ontrain.estimator import OnboardEstimator
    from torquemod.ontrain.onboardconfig import OnboardConfig
    from torquemod.ontrain.run import estimate_axle

    run = read_run(folder / "run.toml")
    e = run.recordings[0]
    base_now = _rss_now_bytes()
    t0, c0 = time.perf_counter(), time.process_time()
    if mode == "streamed":
        windows = len(estimate_axle(run, e).track)
    else:
        rec = read_recording(e.path, group=e.group, channel_map=run.channel_map)
        ch = rec.channels
        est = OnboardEstimator(run.vehicle, run.modulation_frequency_hz, rec.fs_hz,
                               config=OnboardConfig(), t0_s=rec.t0_s)
        step, windows = round(30.0 * rec.fs_hz), 0
        for a in range(0, rec.n_samples, step):
            windows += len(est.feed(*(np.asarray(ch[c][a:a + step]) for c in (
                "torque_nm", "wheel_speed_rad_s", "vehicle_speed_m_s", "position_m"))))
    return {"baseline_rss": base_now, "peak_rss": _rss_peak_bytes(), "windows": windows,
            "wall_s": time.perf_counter() - t0, "cpu_s": time.process_time() - c0}


def train(hours_list: list[float], workdir: str | None) -> None:
    import shutil

    mib = 2**20
    print(f"a train run through the on-board estimator (HDF5: torque and wheel speed at "
          f"{TRAIN_FS_HZ:.0f} Hz, reference speed and position at {TRAIN_REF_HZ:.0f} Hz)")
    print(f"{'length':>8s} {'file MiB':>9s} {'mode':>9s} {'peak RSS above baseline':>24s} "
          f"{'copies':>7s} {'windows':>8s} {'CPU s':>7s} {'x real time':>11s}")
    tmp = Path(tempfile.mkdtemp(dir=workdir))
    try:
        for hours in hours_list:
            folder = tmp / f"run_{hours:g}h"
            n = generate_train(folder, hours)
            one_copy = n * 4 * 8  # time, torque, wheel speed and the interpolated reference
            size = (folder / "run.h5").stat().st_size
            for mode in ("streamed", "whole"):
                m, used = _in_fresh_process("--_train", str(folder), "--_mode", mode)
                print(f"{hours:7.3g}h {size / mib:9.0f} {mode:>9s} {used / mib:20.0f} MiB "
                      f"{used / one_copy:7.3f} {m['windows']:8d} {m['cpu_s']:7.1f} "
                      f"{hours * 3600 / m['cpu_s']:11.0f}", flush=True)
            shutil.rmtree(folder)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reading", type=float, nargs="+", default=None, metavar="HOURS",
                    help="measure reading alone, whole vs streamed, for these lengths [h]")
    ap.add_argument("--keep", action="store_true", help="keep the generated files")
    ap.add_argument("--chain", action="store_true",
                    help="with --reading: also stream revolution by revolution through the "
                         "per-cycle chain (steps 1-5, 8 and the phase)")
    ap.add_argument("--train", type=float, nargs="+", default=None, metavar="HOURS",
                    help="a train run of these lengths [h] through the on-board estimator")
    ap.add_argument("--command", type=float, nargs="+", default=None, metavar="MINUTES",
                    help="peak RSS of `torquemod process` itself on recordings of these "
                         "lengths [min]")
    ap.add_argument("--dtype", choices=["f8", "f4"], default="f8",
                    help="with --command: sample type stored in the HDF5 file")
    ap.add_argument("--sample", type=float, default=None, metavar="SECONDS",
                    help="with --command: also sample the child's VmRSS this often and "
                    "print where its peak falls (e.g. 0.01)")
    ap.add_argument("--layout", nargs="+", default=None, metavar="LAYOUT",
                    help="with --command: how the recording is written, one run per layout "
                         "and length (benchmarks/_layouts.py: chunk64k (default), contiguous, "
                         "contiguous-time, auto, resizable, chunk1m, chunk4m, gzip, gzip1m, "
                         "gzip4m, mat73, tdms, mdf4, parquet, csv); the results of each are "
                         "compared with the first layout's")
    ap.add_argument("--nan", choices=["interpolate", "drop-cycle"], default=None,
                    help="with --command: write a few runs of NaN/inf into each recording "
                         "(NAN_RUNS, HDF5 layouts) and process it with this --nan-policy")
    ap.add_argument("--keep-results", default=None, metavar="DIR",
                    help="with --command: copy each results folder into DIR")
    ap.add_argument("--src", default=None,
                    help="with --command: the torquemod sources to run (default: this "
                         "checkout's src; another checkout's for a before/after pair)")
    ap.add_argument("--_train", default=None, help=argparse.SUPPRESS)
    ap.add_argument("--_long", default=None, help=argparse.SUPPRESS)
    ap.add_argument("--_damage", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--_read", default=None, help=argparse.SUPPRESS)
    ap.add_argument("--_mode", default="whole", help=argparse.SUPPRESS)
    ap.add_argument("--minutes", type=float, default=15.0)
    ap.add_argument("--workdir", default=None)
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--tracemalloc", action="store_true")
    ap.add_argument("--_generate", default=None, help=argparse.SUPPRESS)
    ap.add_argument("--_measure", default=None, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.workdir:  # a folder that does not exist yet is made (temporary folders go in it)
        Path(args.workdir).mkdir(parents=True, exist_ok=True)
    if args._read:
        print(json.dumps(measure_read(Path(args._read), args._mode)))
        return
    if args._train:
        print(json.dumps(measure_train(Path(args._train), args._mode)))
        return
    if args._long:
        gen = generate_long(Path(args._long), args.minutes, args.dtype,
                            layout=(args.layout or ["chunk64k"])[0])
        if args._damage:
            gen["nonfinite"] = damage(Path(args._long) / gen["file"])
        print(json.dumps(gen))
        return
    if args.train:
        train(args.train, args.workdir)
        return
    if args.command:
        command(args.command, args.workdir, args.dtype, args.src, args.sample, args.layout,
                args.nan, args.keep_results)
        return
    if args.reading:
        reading(args.reading, args.workdir, args.keep, args.chain)
        return
    if args._generate:
        print(json.dumps(generate(Path(args._generate), args.minutes)))
        return
    if args._measure:
        folder = Path(args._measure)
        print(json.dumps(measure(folder, args.workers or 2, args.tracemalloc,
                                 folder.parent / "results")))
        return
    with tempfile.TemporaryDirectory(dir=args.workdir) as tmp:
        folder = Path(tmp) / "experiment"
        here = [sys.executable, __file__, "--minutes", str(args.minutes)]
        gen = json.loads(subprocess.run([*here, "--_generate", str(folder)], check=True,
                                        capture_output=True, text=True).stdout)
        cmd = [*here, "--_measure", str(folder)]
        if args.workers:
            cmd += ["--workers", str(args.workers)]
        if args.tracemalloc:
            cmd += ["--tracemalloc"]
        m = json.loads(subprocess.run(cmd, check=True, capture_output=True,
                                      text=True).stdout)
    hours = gen["duration_s"] / 3600
    one_copy = gen["n_samples"] * N_CHANNELS * 8
    used = m["peak_rss"] - m["baseline_rss"]
    mib = 2**20
    print(f"recording: {gen['duration_s'] / 60:.1f} min at {FS_HZ:.0f} Hz, "
          f"{gen['n_samples']:,} samples, {gen['revolutions']} revolutions "
          f"({m['n_cycles']} cycles processed in {m['wall_s']:.1f} s)")
    print(f"one copy (7 x float64):      {one_copy / mib:8.0f} MiB "
          f"= {one_copy / hours / 2**30:.2f} GiB per recorded hour")
    print(f"peak RSS above baseline:     {used / mib:8.0f} MiB "
          f"= {used / hours / 2**30:.2f} GiB per recorded hour "
          f"= {used / one_copy:.2f} copies (baseline {m['baseline_rss'] / mib:.0f} MiB)")
    if m["traced_peak"] is not None:
        tr = m["traced_peak"]
        print(f"peak traced allocations:     {tr / mib:8.0f} MiB "
              f"= {tr / hours / 2**30:.2f} GiB per recorded hour = {tr / one_copy:.2f} copies")


if __name__ == "__main__":
    main()
