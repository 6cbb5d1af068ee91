"""`process` in bounded memory: a step that is one recording of many revolutions is aligned
and measured cycle by cycle while it is read (torquemod.processing.stepmeasure.InOrderStep), and
figure traces are kept for the first pipeline.TRACE_CYCLES cycles of a step only.

Reference: the same recordings with every cycle held until the end and the step aligned at
once (process_experiment(loaded=...), the fleet's path, which never measures while reading).
The numbers must be equal bit for bit: the same functions run on the same samples.
"""

from __future__ import annotations

import json
import sys

import numpy as np
import pandas as pd
import pytest

import torquemod.processing.pipeline as pl
from torquemod.errors import InputError, ProcessingError
from torquemod.io import read_experiment
from torquemod.testing import write_synthetic_experiment


def _held_to_the_end(manifest):
    exp = read_experiment(manifest)
    cfg = pl.resolve_config(exp)
    loaded = [(e, pl.load_and_process(e, exp, cfg)) for e in exp.recordings]
    return pl.process_experiment(exp, workers=1, loaded=loaded)


@pytest.mark.parametrize("streamed", [False, True])
def test_measured_while_read_equals_the_step_aligned_at_the_end(tmp_path, monkeypatch,
                                                               streamed):
    write_synthetic_experiment(tmp_path, n_steps=2, n_cycles=4, files_per_cycle=False,
                               fmt="hdf5", seed=7)
    manifest = tmp_path / "experiment.toml"
    monkeypatch.setattr(pl, "TRACE_CYCLES", 2)
    if streamed:
        monkeypatch.setattr(pl, "STREAM_MIN_BYTES", 0)
    seen = []
    real = pl.InOrderStep.__call__

    def spy(self, item):
        seen.append((self.step, item[0]))
        return real(self, item)

    monkeypatch.setattr(pl.InOrderStep, "__call__", spy)
    got = pl.process_experiment(manifest, workers=2)
    assert sorted(seen) == [(s, c) for s in (1, 2) for c in (1, 2, 3, 4)]  # the path ran
    n_seen = len(seen)
    ref = _held_to_the_end(manifest)
    assert len(seen) == n_seen  # the reference did not measure while reading
    pd.testing.assert_frame_equal(got.cycles, ref.cycles, check_exact=True)
    pd.testing.assert_frame_equal(got.steps, ref.steps, check_exact=True)
    assert (json.dumps(list(got.cycle_details), default=str)
            == json.dumps(list(ref.cycle_details), default=str))
    assert got.warnings == ref.warnings
    # traces: the first two cycles of each step, the same arrays under the same names
    assert sorted(got.traces) == sorted(ref.traces) == [(1, 1), (1, 2), (2, 1), (2, 2)]
    for key, arrays in ref.traces.items():
        assert list(got.traces[key]) == list(arrays)
        for name, x in arrays.items():
            np.testing.assert_array_equal(got.traces[key][name], x)


def test_phase_error_is_raised_in_step_order(tmp_path, monkeypatch):
    """A cycle whose phase cannot be measured while it is read raises the same one-line
    error as when the step is measured at the end."""
    write_synthetic_experiment(tmp_path, n_steps=1, n_cycles=2, files_per_cycle=False,
                               fmt="hdf5", seed=3)

    def fail(*args, **kwargs):
        raise ProcessingError("no peaks")

    monkeypatch.setattr(pl.chain, "cycle_phase", fail)
    with pytest.raises(InputError, match="phase not measurable: no peaks") as a:
        pl.process_experiment(tmp_path / "experiment.toml", workers=1)
    with pytest.raises(InputError, match="phase not measurable: no peaks") as b:
        _held_to_the_end(tmp_path / "experiment.toml")
    assert str(a.value) == str(b.value)


def test_binary_file_streamed_by_its_decoded_size(tmp_path, monkeypatch):
    """An HDF5 file smaller on disk than STREAM_MIN_BYTES whose samples take at least
    STREAM_MIN_DECODED_BYTES as float64 (with the time base) is streamed, with the
    whole-file path's numbers."""
    write_synthetic_experiment(tmp_path, n_steps=1, n_cycles=2, files_per_cycle=False,
                               fmt="hdf5", seed=5)
    manifest = tmp_path / "experiment.toml"
    whole = pl.process_experiment(manifest, workers=1)
    (path,) = tmp_path.glob("*.h5")
    exp = read_experiment(manifest)
    with pl.open_stream(exp.recordings[0], experiment=exp) as s:
        decoded = 8 * s.info.n_samples * (len(s.info.channels) + 1)
    size = path.stat().st_size
    assert decoded > size  # the time base is not stored as a column
    streamed = []
    real = pl._streamed_cycles
    monkeypatch.setattr(pl, "_streamed_cycles",
                        lambda *a, **k: streamed.append(a) or real(*a, **k))
    monkeypatch.setattr(pl, "STREAM_MIN_BYTES", size + 1)
    monkeypatch.setattr(pl, "STREAM_MIN_DECODED_BYTES", decoded)
    same = pl.process_experiment(manifest, workers=1)
    assert len(streamed) == 1
    pd.testing.assert_frame_equal(same.cycles, whole.cycles, check_exact=True)
    monkeypatch.setattr(pl, "STREAM_MIN_DECODED_BYTES", decoded + 1)  # neither: read whole
    pl.process_experiment(manifest, workers=1)
    assert len(streamed) == 1


@pytest.mark.parametrize("fmt", ["tdms", "mdf"])
def test_tdms_and_mdf_streamed_by_their_decoded_size(tmp_path, monkeypatch, write_columns,
                                                     fmt):
    """TDMS and MDF4 files, whose sample counts are in their metadata, are streamed by
    their decoded size as HDF5 is (a 10-min float32 TDMS recording, 229 MiB on disk, was
    read whole), with the numbers of the same file read whole: bit for bit from TDMS's
    waveform rate; from MDF4's master the stream fits the time stamps summed by block, which
    gives the sample rate to 1e-12 relative (tests/io/test_stream.py), the cycles to 1e-9."""
    pytest.importorskip("nptdms" if fmt == "tdms" else "asammdf")
    from torquemod.io import read_recording
    write_synthetic_experiment(tmp_path, n_steps=1, n_cycles=2, files_per_cycle=False,
                               fmt="hdf5", seed=5)
    manifest = tmp_path / "experiment.toml"
    (h5,) = tmp_path.glob("*.h5")
    rec = read_recording(h5)
    path = write_columns(fmt, h5.with_suffix(".tdms" if fmt == "tdms" else ".mf4"),
                         dict(rec.channels), fs_hz=rec.fs_hz, t0_s=rec.t0_s)
    manifest.write_text(manifest.read_text().replace(h5.name, path.name))
    h5.unlink()
    exp = read_experiment(manifest)
    with pl.open_stream(exp.recordings[0], experiment=exp) as s:
        decoded = 8 * s.info.n_samples * (len(s.info.channels) + 1)
    streamed = []
    real = pl._streamed_cycles
    monkeypatch.setattr(pl, "_streamed_cycles",
                        lambda *a, **k: streamed.append(a) or real(*a, **k))
    monkeypatch.setattr(pl, "STREAM_MIN_BYTES", path.stat().st_size + 1)
    monkeypatch.setattr(pl, "STREAM_MIN_DECODED_BYTES", decoded)
    same = pl.process_experiment(manifest, workers=1)
    assert len(streamed) == 1
    monkeypatch.setattr(pl, "STREAM_MIN_DECODED_BYTES", decoded + 1)  # read whole
    whole = pl.process_experiment(manifest, workers=1)
    assert len(streamed) == 1
    if fmt == "tdms":
        pd.testing.assert_frame_equal(same.cycles, whole.cycles, check_exact=True)
    else:
        pd.testing.assert_frame_equal(same.cycles, whole.cycles, check_exact=False,
                                      rtol=1e-9)


def test_files_written_from_columnar_details_equal_those_from_dicts(tmp_path):
    """result.json, provenance.json and report.html are written one cycle's details at a
    time from the columns; the text must be that of the same details as a list of dicts."""
    import dataclasses

    import torquemod as tm
    from torquemod._util.records import ColumnarRecords

    write_synthetic_experiment(tmp_path / "exp", n_steps=2, n_cycles=3,
                               files_per_cycle=False, fmt="hdf5", seed=3)
    res = tm.process(tmp_path / "exp" / "experiment.toml")
    assert isinstance(res.cycle_details, ColumnarRecords) and len(res.cycle_details) == 6
    ana = tm.analyze(res)
    as_dicts = dataclasses.replace(res, cycle_details=list(res.cycle_details))
    tm.save(res, ana, tmp_path / "out_qzc")
    tm.save(as_dicts, ana, tmp_path / "out_qzd")
    for name in ("result.json", "provenance.json", "report.html"):
        got = (tmp_path / "out_qzc" / name).read_text(encoding="utf-8")
        want = (tmp_path / "out_qzd" / name).read_text(encoding="utf-8")
        assert got.replace("out_qzc", "out_qzd") == want, name
        assert '"slip"' in got or "&quot;slip&quot;" in got  # the details are in it


def test_run_imports_the_report_after_processing(tmp_path):
    """`torquemod process` loads the analysis, layout and report modules (matplotlib) only
    once the recordings are processed, so that they do not add to the processing's peak."""
    import subprocess
    import sys

    write_synthetic_experiment(tmp_path / "exp", n_steps=1, n_cycles=2, fmt="hdf5", seed=1)
    code = ("import sys, torquemod.api as api\n"
            "real = api.process\n"
            "def spy(*a, **k):\n"
            "    print(sorted(m for m in ('torquemod.report', 'torquemod.results.folder',\n"
            "                 'torquemod.analysis.analyzer') if m in sys.modules))\n"
            "    return real(*a, **k)\n"
            "api.process = spy\n"
            "api.run(sys.argv[1], sys.argv[2], fit=False)\n")
    out = subprocess.run([sys.executable, "-c", code, str(tmp_path / "exp"),
                          str(tmp_path / "out")], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
    assert (tmp_path / "out" / "result.json").is_file()


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="/proc/self/smaps: Linux")
def test_processing_leaves_no_compiler_memory_behind(tmp_path):
    """After `process_experiment` the chain's kernels, loaded from numba's cache, hold no
    parsed LLVM module, and LLVM's library pages are out of the resident set
    (torquemod._util.jitlink): ~59 and ~65 MiB of the command's peak on a long recording."""
    import subprocess

    write_synthetic_experiment(tmp_path / "exp", n_steps=1, n_cycles=2, fmt="hdf5", seed=2)
    code = ("import gc, json, os, sys\n"
            "from numba.core.dispatcher import Dispatcher\n"
            "from torquemod.processing.pipeline import process_experiment\n"
            "def llvm_kib():\n"
            "    total, mine = 0, False\n"
            "    for line in open('/proc/self/smaps'):\n"
            "        h = line.split()\n"
            "        if '-' in h[0] and not h[0].endswith(':'):\n"
            "            mine = len(h) > 5 and 'libllvmlite' in os.path.basename(h[5])\n"
            "        elif mine and h[0] == 'Rss:':\n"
            "            total += int(h[1])\n"
            "    return total\n"
            "for run in (1, 2):  # the first run may compile (a cold cache), the second loads\n"
            "    res = process_experiment(sys.argv[1], workers=1)\n"
            "libs = [c.library for d in gc.get_objects() if isinstance(d, Dispatcher)\n"
            "        for c in d.overloads.values()]\n"
            "print(json.dumps({'cycles': len(res.cycles), 'llvm_kib': llvm_kib(),\n"
            "                  'held': sum(lib._shared_module is not None for lib in libs),\n"
            "                  'cached': sum('_torquemod_linking_bitcode' in vars(lib)\n"
            "                                for lib in libs)}))\n")
    # a fresh interpreter twice: the first fills numba's cache if this tree's is cold
    for _ in range(2):
        out = subprocess.run([sys.executable, "-c", code, str(tmp_path / "exp")],
                             capture_output=True, text=True)
        assert out.returncode == 0, out.stderr
    got = json.loads(out.stdout)
    assert got["cycles"] == 2
    assert got["cached"] >= 10  # the chain's kernels came from the cache ...
    assert got["held"] == 0  # ... without their parsed modules
    assert got["llvm_kib"] < 16_384  # LLVM's pages released (~65 MiB touched when loading)
