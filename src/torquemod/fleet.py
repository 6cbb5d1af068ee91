"""Many experiments at once on Dask (issue 11): one task per run manifest, in worker processes.

:func:`run_fleet` sends each run manifest to a Dask worker process (a ``LocalCluster`` of
processes sized to the machine, or an existing scheduler). A worker reads and processes the
run with :func:`torquemod.pipeline.process_experiment` (one thread: the processes are the
parallelism, since the GIL makes threads of this chain useless) and writes its tables as
partitions of Parquet datasets::

    OUT/cycles/run=<run>/part-0.parquet    per-cycle table of every run
    OUT/steps/run=<run>/part-0.parquet     per-step table of every run
    OUT/fleet_summary.csv                  one row per run: status, counts, seconds, message
    OUT/failures.csv                       one row per failed run: the one-line message
    OUT/_state/<run>.json                  fingerprint of what produced the partitions

pandas, Dask and DuckDB read ``OUT/cycles`` directly (hive partitioning gives the ``run``
column). A bad run never stops the fleet: its error, the same text ``torquemod process``
prints after ``torquemod: error:``, becomes a row of the failures table. A rerun skips a run
whose fingerprint (SHA-256 of the manifest and of every recording, the processing
parameters, the torquemod version) is unchanged and whose partitions are in place; a file
whose size and modification time are unchanged keeps its recorded digest.
"""

from __future__ import annotations

import glob
import hashlib
import json
import shutil
import time
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from ._version import __version__
from .errors import InputError, TorquemodError

MANIFEST_NAME = "experiment.toml"
SUMMARY_COLUMNS = ["run", "status", "manifest", "n_steps", "n_cycles", "seconds", "message"]


def find_manifests(runs: Iterable[str | Path]) -> list[Path]:
    """Run manifests from ``runs``: manifest files, folders (every ``experiment.toml``
    below them), glob patterns, or list files (``.txt``/``.lst``: one of the above a line,
    ``#`` comments). Sorted, without duplicates."""
    found: list[Path] = []
    for item in runs:
        text = str(item)
        path = Path(text)
        if path.is_dir():
            found += sorted(path.rglob(MANIFEST_NAME))
        elif path.is_file() and path.suffix.lower() in (".txt", ".lst"):
            lines = [ln.split("#", 1)[0].strip() for ln in path.read_text().splitlines()]
            found += find_manifests([path.parent / ln for ln in lines if ln])
        elif path.is_file():
            found.append(path)
        elif any(ch in text for ch in "*?["):
            found += find_manifests(sorted(glob.glob(text, recursive=True)))
        else:
            raise InputError("no such run manifest, folder or list", path=path,
                             hint="give experiment.toml files, folders holding them, a glob "
                                  "or a .txt list of them")
    return sorted(dict.fromkeys(p.resolve() for p in found))


def run_names(manifests: list[Path]) -> list[str]:
    """A partition name per manifest: its folder's name, with a short hash of the full path
    when two folders share a name."""
    base = [m.parent.name or m.stem for m in manifests]
    out = []
    for m, b in zip(manifests, base, strict=True):
        safe = "".join(ch if ch.isalnum() or ch in "-_." else "_" for ch in b)
        if base.count(b) > 1:
            safe += "-" + hashlib.sha256(str(m).encode()).hexdigest()[:8]
        out.append(safe)
    return out


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        while block := fh.read(1 << 22):
            h.update(block)
    return h.hexdigest()


def _file_digest(path: Path, known: dict) -> list:
    """``[size, mtime_ns, sha256]`` of a file; the digest in ``known[str(path)]`` is reused
    when size and modification time are unchanged (a rerun does not read every file again
    just to find it unchanged; the usual assumption of make and rsync)."""
    st = path.stat()
    old = known.get(str(path))
    if old and old[0] == st.st_size and old[1] == st.st_mtime_ns:
        return list(old)
    return [st.st_size, st.st_mtime_ns, _sha256(path)]


def fingerprint(manifest: Path, known: dict | None = None) -> tuple[str, object, dict]:
    """``(hex digest, experiment, files)``: SHA-256 over the manifest's and each recording's
    SHA-256, the processing parameters and the torquemod version; ``files`` maps each file
    to ``[size, mtime_ns, sha256]`` (pass it back as ``known`` next time)."""
    from .io import read_experiment
    known = known or {}
    exp = read_experiment(manifest)
    cfg = exp.processing
    files = {str(Path(exp.manifest_path)): _file_digest(Path(exp.manifest_path), known)}
    for path in sorted({str(e.path) for e in exp.recordings}):
        if Path(path).is_file():
            files[path] = _file_digest(Path(path), known)
    h = hashlib.sha256()
    for path, (_, _, digest) in sorted(files.items()):
        h.update(f"{path}\0{digest}\0".encode())
    h.update(json.dumps(cfg.to_dict(), sort_keys=True, default=str).encode())
    h.update(__version__.encode())
    return h.hexdigest(), exp, files


def _write_partition(df: pd.DataFrame, folder: Path) -> None:
    """``df`` as ``folder/part-0.parquet``, replacing the folder at once (written beside it,
    then renamed), so a reader never sees half a partition."""
    tmp = folder.with_name(folder.name + ".tmp")
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir(parents=True)
    df.to_parquet(tmp / "part-0.parquet", index=False)
    old = folder.with_name(folder.name + ".old")
    if folder.exists():
        shutil.rmtree(old, ignore_errors=True)
        folder.rename(old)
    tmp.rename(folder)
    shutil.rmtree(old, ignore_errors=True)


def process_run(manifest: str, out_dir: str, run: str, force: bool = False) -> dict:
    """Process one run into its partitions (a Dask task; also usable alone). Never raises:
    the outcome is a summary row (``status`` processed, skipped or failed)."""
    from .pipeline import process_experiment

    t0 = time.perf_counter()
    out = Path(out_dir)
    row = {"run": run, "manifest": str(manifest), "n_steps": 0, "n_cycles": 0,
           "message": ""}
    try:
        state = out / "_state" / f"{run}.json"
        try:
            old = json.loads(state.read_text()) if state.is_file() else {}
        except (OSError, ValueError):
            old = {}
        digest, exp, files = fingerprint(Path(manifest), old.get("files"))
        parts = [out / t / f"run={run}" / "part-0.parquet" for t in ("cycles", "steps")]
        if not force and all(p.is_file() for p in parts):
            if old.get("fingerprint") == digest:
                return {**row, **{k: old[k] for k in ("n_steps", "n_cycles")},
                        "status": "skipped", "seconds": time.perf_counter() - t0}
        res = process_experiment(exp, workers=1)
        _write_partition(res.cycles, out / "cycles" / f"run={run}")
        _write_partition(res.steps, out / "steps" / f"run={run}")
        row.update(n_steps=len(res.steps), n_cycles=len(res.cycles))
        state.parent.mkdir(parents=True, exist_ok=True)
        state.write_text(json.dumps({"fingerprint": digest, "manifest": str(manifest),
                                     "n_steps": row["n_steps"],
                                     "n_cycles": row["n_cycles"], "files": files}))
        row["status"] = "processed"
    except TorquemodError as exc:
        row.update(status="failed", message=str(exc).splitlines()[0])
    except Exception as exc:  # a bug or a library failure: reported, the fleet goes on
        row.update(status="failed",
                   message=f"internal error: {type(exc).__name__}: {exc}".splitlines()[0])
    if row["status"] == "failed":
        for t in ("cycles", "steps"):  # no stale results of an earlier good run
            shutil.rmtree(out / t / f"run={run}", ignore_errors=True)
        (out / "_state" / f"{run}.json").unlink(missing_ok=True)
    row["seconds"] = time.perf_counter() - t0
    return row


@dataclass(frozen=True)
class FleetResult:
    """What :func:`run_fleet` did: ``summary`` (one row per run, :data:`SUMMARY_COLUMNS`),
    ``failures`` (its failed rows), the output folder and the dashboard address (None when
    the cluster has none)."""

    out_dir: Path
    summary: pd.DataFrame
    failures: pd.DataFrame
    dashboard: str | None
    wall_s: float

    def count(self, status: str) -> int:
        return int((self.summary["status"] == status).sum())


def run_fleet(manifests: Iterable[str | Path], out_dir: str | Path, *,
              scheduler: str | None = None, n_workers: int | None = None,
              force: bool = False, progress: bool = False,
              on_dashboard=None) -> FleetResult:
    """Process many run manifests in parallel on Dask and write the fleet's datasets.

    ``manifests`` as :func:`find_manifests` takes them. ``scheduler`` is the address of an
    existing Dask scheduler (``tcp://host:8786``); None starts a ``LocalCluster`` of
    ``n_workers`` single-threaded worker processes (default: the CPU count) and stops it
    at the end. ``force`` reprocesses unchanged runs. ``on_dashboard(link)`` is called with
    the dashboard address when there is one; ``progress`` shows a bar on stderr.
    """
    from dask.distributed import as_completed
    from tqdm import tqdm

    from .daskutil import dask_client

    paths = find_manifests(manifests)
    if not paths:
        raise InputError("no run manifests found", hint="give experiment.toml files, "
                         "folders holding them, a glob or a list file")
    out = Path(out_dir).resolve()
    out.mkdir(parents=True, exist_ok=True)
    names = run_names(paths)
    t0 = time.perf_counter()
    rows = []
    links: list[str] = []

    def dashboard(link: str) -> None:
        links.append(link)
        if on_dashboard is not None:
            on_dashboard(link)

    with dask_client(scheduler, n_workers, dashboard) as client:
        futures = [client.submit(process_run, str(p), str(out), name, force, pure=False,
                                 key=f"torquemod-run-{name}-{time.time_ns()}")
                   for p, name in zip(paths, names, strict=True)]
        bar = tqdm(total=len(futures), desc="fleet", unit="run", disable=not progress)
        for fut in as_completed(futures):
            rows.append(fut.result())
            bar.update()
        bar.close()
    link = links[0] if links else None
    summary = pd.DataFrame(rows, columns=SUMMARY_COLUMNS).sort_values("run",
                                                                      ignore_index=True)
    failures = summary.loc[summary["status"] == "failed",
                           ["run", "manifest", "message"]].reset_index(drop=True)
    summary.to_csv(out / "fleet_summary.csv", index=False)
    failures.to_csv(out / "failures.csv", index=False)
    return FleetResult(out, summary, failures, link if link else None,
                       time.perf_counter() - t0)
