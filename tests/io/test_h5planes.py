"""Large deflate-compressed HDF5 chunks streamed by planes (torquemod.io._h5planes), against
h5py reading the same datasets whole: the same values, bit for bit, in the same type.

Small files take the path here by lowering ``MIN_CHUNK_BYTES``; the memory test writes
chunks of the size that held 6 x 32 MiB in ``torquemod process`` (2**22 float64 samples).
"""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from torquemod.errors import InputError
from torquemod.io import _h5planes
from torquemod.io._stream_tables import _H5Table

N = 50_003  # rows: the last chunk is partial


def _blocks(table: _H5Table, names: list[str], rows: int) -> dict[str, np.ndarray]:
    """The blocks of ``names`` joined (in the blocks' type: concatenate makes it native)."""
    table.n_rows = table.column_length(names[0])
    got = list(table.blocks(names, rows))
    assert all(b[names[0]].size == rows for b in got[:-1])
    for n in names:
        assert len({b[n].dtype for b in got}) == 1
    return {n: np.concatenate([b[n] for b in got]).astype(got[0][n].dtype) for n in names}


@pytest.fixture
def layouts(tmp_path, monkeypatch):
    """A file with a dataset per layout; the path taken by any chunk size."""
    import h5py
    monkeypatch.setattr(_h5planes, "MIN_CHUNK_BYTES", 0)
    rng = np.random.default_rng(3)
    x = np.cumsum(rng.standard_normal(N))
    path = tmp_path / "planes.h5"
    gz = {"compression": "gzip", "compression_opts": 4}
    with h5py.File(path, "w") as fh:
        fh.create_dataset("f8_shuffle", data=x, chunks=(4_096,), shuffle=True, **gz)
        fh.create_dataset("f4_be_shuffle", data=x.astype(">f4"), chunks=(6_000,),
                          shuffle=True, **gz)
        fh.create_dataset("f8_deflate", data=x, chunks=(8_192,), **gz)
        fh.create_dataset("one_chunk", data=x, chunks=(N,), shuffle=True, **gz)
        ds = fh.create_dataset("i2_scaled", data=(100 * x).astype(np.int16), chunks=(5_000,),
                               shuffle=True, **gz)
        ds.attrs["scale_factor"] = 0.01
        ds.attrs["add_offset"] = 3.0
        fh.create_dataset("fletcher", data=x, chunks=(4_096,), shuffle=True,
                          fletcher32=True, **gz)
        fh.create_dataset("lzf", data=x, chunks=(4_096,), shuffle=True, compression="lzf")
        fh.create_dataset("plain", data=x, chunks=(4_096,))
    return path


def test_planes_give_hdf5s_values(layouts):
    """Every layout streamed in blocks that end inside chunks and across chunk ends gives
    h5py's values and type; deflate and shuffle+deflate take the planes, the others HDF5."""
    import h5py
    names = ["f8_shuffle", "f4_be_shuffle", "f8_deflate", "one_chunk", "i2_scaled",
             "fletcher", "lzf", "plain"]
    table = _H5Table(layouts, None, mat=False)
    try:
        for rows in (777, 10_000):
            got = _blocks(table, names, rows)
            with h5py.File(layouts, "r") as fh:
                for n in names:
                    want = fh[n][:]
                    if n == "i2_scaled":
                        want = want.astype(np.float64) * 0.01 + 3.0
                    assert got[n].dtype == want.dtype, n
                    np.testing.assert_array_equal(got[n], want, err_msg=n)
        planes = {n for n in names if table._layouts[n] is not None}
        assert planes == {"f8_shuffle", "f4_be_shuffle", "f8_deflate", "one_chunk",
                          "i2_scaled"}
    finally:
        table.close()


def test_plane_reader_starts_anywhere(layouts):
    """Reads continuing, jumping back and starting inside a chunk give the same rows."""
    import h5py
    with h5py.File(layouts, "r") as fh, open(layouts, "rb") as raw:
        ds = fh["f8_shuffle"]
        want = ds[:]
        reader = _h5planes.PlaneReader(_h5planes.plane_layout(ds), raw)
        for a, b in ((10_001, 12_000), (12_000, 20_481), (5, 7), (4_095, 4_097),
                     (49_000, N)):
            np.testing.assert_array_equal(reader.rows(a, b), want[a:b])


def test_damaged_chunk_names_file_and_channel(layouts):
    import h5py
    with h5py.File(layouts, "r") as fh:
        info = fh["f8_shuffle"].id.get_chunk_info(3)
    with open(layouts, "r+b") as raw:
        raw.seek(info.byte_offset)
        raw.write(b"\x00\x00\x00\x00")  # no zlib header
    table = _H5Table(layouts, None, mat=False)
    try:
        with pytest.raises(InputError, match="cannot read 'f8_shuffle'") as e:
            _blocks(table, ["f8_shuffle"], 1_000)
        assert str(layouts.name) in str(e.value)
    finally:
        table.close()


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="/proc/self/statm: Linux")
def test_large_compressed_chunks_are_not_held_whole(tmp_path):
    """Two channels in gzip + shuffle chunks of 2**22 float64 samples (32 MiB decoded),
    streamed 65 536 rows at a time in a fresh process: the resident size after each block
    stays within 16 MiB of that before the first. Through HDF5's chunk cache each channel
    held its decoded chunk between blocks (+64 MiB here; ``ru_maxrss`` cannot tell, a
    child's includes its parent's peak)."""
    import h5py
    n = 1 << 22
    t = np.arange(n) / 16_670.0
    path = tmp_path / "big.h5"
    with h5py.File(path, "w") as fh:
        for k in range(2):
            x = np.round(np.sin(2 * np.pi * (2.0 + k) * t), 3)  # compresses quickly
            fh.create_dataset(f"c{k}", data=x, chunks=(n,), compression="gzip",
                              compression_opts=1, shuffle=True)
    code = ("import json, os, sys\n"
            "from pathlib import Path\n"
            "from torquemod.io._stream_tables import _H5Table\n"
            "def rss():\n"
            "    with open('/proc/self/statm') as fh:\n"
            "        return int(fh.read().split()[1]) * os.sysconf('SC_PAGE_SIZE')\n"
            "t = _H5Table(Path(sys.argv[1]), None, mat=False)\n"
            "t.n_rows = t.column_length('c0')\n"
            "base, grew, total = rss(), 0, 0.0\n"
            "for b in t.blocks(['c0', 'c1'], 65_536):\n"
            "    total += float(b['c0'].sum() + b['c1'].sum())\n"
            "    grew = max(grew, rss() - base)\n"
            "t.close()\n"
            "print(json.dumps({'grew': grew, 'total': total}))\n")
    out = subprocess.run([sys.executable, "-c", code, str(path)], capture_output=True,
                         text=True)
    assert out.returncode == 0, out.stderr
    got = json.loads(out.stdout)
    with h5py.File(path, "r") as fh:
        assert got["total"] == pytest.approx(float(fh["c0"][:].sum() + fh["c1"][:].sum()),
                                             rel=1e-12)
    assert got["grew"] < 16 * 2**20  # one decoded chunk is 32 MiB
