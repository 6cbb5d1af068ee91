"""Damaged files of every format: the readers raise InputError (or return a valid recording),
never another exception, never crash the interpreter, never hang.

The damage is seeded random (truncation, scattered byte changes, overwritten blocks), so a
failure names a case that can be replayed. The count per format is bounded so the file runs in
a few seconds.
"""

from __future__ import annotations

import gc
import signal
import struct
import zlib
from pathlib import Path

import numpy as np
import pytest
import scipy.io

from torquemod.errors import InputError
from torquemod.io import read_recording
from torquemod.io.experiment import CHANNELS, Recording
from torquemod.io.validate import check_channels

CASES_PER_KIND = 25  # x 3 kinds of damage x 8 formats
SECONDS_PER_READ = 10.0
FORMATS = {"csv": ".csv", "hdf5": ".h5", "tdms": ".tdms", "mdf": ".mf4", "mat5": ".mat",
           "mat5z": ".mat", "mat73": ".mat", "parquet": ".parquet"}


class _Hang(Exception):
    pass


def _alarm(signum, frame):
    raise _Hang


@pytest.fixture(scope="module")
def base_files(tmp_path_factory, write_columns) -> dict[str, Path]:
    """One small valid recording per format."""
    folder = tmp_path_factory.mktemp("fuzz_base")
    rng = np.random.default_rng(7)
    n = 48
    columns = {"time_s": np.arange(n) / 100.0,
               **{c: rng.standard_normal(n) for c in CHANNELS}}
    out = {}
    for fmt, suffix in FORMATS.items():
        path = folder / f"base_{fmt}{suffix}"
        if fmt == "mat5z":  # MATLAB's default: every variable zlib-compressed
            scipy.io.savemat(path, {k: v.reshape(-1, 1) for k, v in columns.items()},
                             do_compression=True)
        else:
            write_columns(fmt, path, columns, fs_hz=100.0)
        read_recording(path)  # the undamaged file reads
        out[fmt] = path
    return out


def _damaged(data: bytes, kind: str, rng: np.random.Generator) -> bytes:
    b = bytearray(data)
    if kind == "truncate":
        return bytes(b[: int(rng.integers(0, len(b)))])
    if kind == "bytes":
        for _ in range(int(rng.integers(1, 9))):
            b[int(rng.integers(len(b)))] = int(rng.integers(256))
        return bytes(b)
    start = int(rng.integers(len(b)))
    stop = min(len(b), start + int(rng.integers(1, 64)))
    b[start:stop] = rng.integers(0, 256, size=stop - start, dtype=np.uint8).tobytes()
    return bytes(b)


def _outcome(path: Path) -> str | None:
    """None when reading ``path`` behaves (InputError or a valid Recording), else why not."""
    previous = signal.signal(signal.SIGALRM, _alarm)
    signal.setitimer(signal.ITIMER_REAL, SECONDS_PER_READ)
    try:
        rec = read_recording(path)
    except InputError:
        return None
    except _Hang:
        return f"no answer within {SECONDS_PER_READ} s"
    except Exception as exc:
        return f"{type(exc).__name__}: {exc}"
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
    if not isinstance(rec, Recording) or not np.isfinite(rec.fs_hz) or rec.fs_hz <= 0:
        return f"returned {rec!r}"
    check_channels(rec, path=path)
    return None


@pytest.mark.parametrize("kind", ["truncate", "bytes", "block"])
@pytest.mark.parametrize("fmt", list(FORMATS))
def test_damaged_files_raise_input_error(fmt, kind, base_files, tmp_path):
    data = base_files[fmt].read_bytes()
    rng = np.random.default_rng(zlib.crc32(f"{fmt}/{kind}".encode()))
    failures = []
    for i in range(CASES_PER_KIND):
        path = tmp_path / f"case{i}{FORMATS[fmt]}"
        path.write_bytes(_damaged(data, kind, rng))
        why = _outcome(path)
        if why:
            failures.append(f"case {i}: {why}")
    gc.collect()  # half-built library objects report their cleanup inside this test
    assert not failures, f"{fmt}/{kind}:\n" + "\n".join(failures)


@pytest.mark.parametrize("fmt", list(FORMATS))
def test_empty_garbage_and_foreign_files(fmt, base_files, tmp_path):
    suffix = FORMATS[fmt]
    rng = np.random.default_rng(3)
    contents = {"empty": b"", "one_byte": b"\0", "garbage": rng.bytes(4096),
                "text": b"time_s,torque_nm\n1,2\n"}
    contents.update({f"from_{other}": p.read_bytes() for other, p in base_files.items()
                     if p.suffix != suffix})
    failures = []
    for name, content in contents.items():
        path = tmp_path / f"{name}{suffix}"
        path.write_bytes(content)
        why = _outcome(path)
        if why:
            failures.append(f"{name}: {why}")
    gc.collect()
    assert not failures, "\n".join(failures)


def test_mat5_unknown_data_type_is_refused(base_files, tmp_path):
    """A damaged element tag that made scipy's compiled reader crash the interpreter."""
    data = bytearray(base_files["mat5"].read_bytes())
    tag = struct.pack("<II", 9, 48 * 8)  # miDOUBLE, 48 values: the first variable's data
    pos = data.index(tag)
    data[pos + 1] = 0xDA
    path = tmp_path / "bad.mat"
    path.write_bytes(bytes(data))
    with pytest.raises(InputError, match=r"bad\.mat: damaged MATLAB file .*unknown data type"):
        read_recording(path)


@pytest.mark.parametrize(("offset", "what"), [(96, "record size"), (80, "record count")])
def test_mdf_damaged_record_layout_is_refused_quickly(offset, what, base_files, tmp_path):
    """Damaged record sizes or counts made asammdf crash or loop for minutes."""
    data = bytearray(base_files["mdf"].read_bytes())
    cg = data.index(b"##CG")
    if what == "record size":
        struct.pack_into("<I", data, cg + offset, 3_000_000_000)
    else:
        struct.pack_into("<Q", data, cg + offset, 2**40)
    path = tmp_path / "bad.mf4"
    path.write_bytes(bytes(data))
    assert _outcome(path) is None
    with pytest.raises(InputError, match=r"bad\.mf4: channel"):
        read_recording(path)
