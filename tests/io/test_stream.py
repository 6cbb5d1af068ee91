"""Streaming readers (torquemod.io.stream) against the whole-file readers, every format.

The reference is :func:`torquemod.io.read_recording` on the same file: the chunks joined must
equal its channels exactly (same conversion arithmetic per element), and the stream's time
base must equal the recording's (to 1e-12: the time-column fit is summed in other blocks).
"""

from __future__ import annotations

import hashlib

import numpy as np
import pytest

from torquemod.errors import InputError
from torquemod.io import read_recording
from torquemod.io.experiment import CHANNELS, RecordingEntry
from torquemod.io.stream import hash_file_async, iter_chunks, open_stream

FS_HZ, T0_S, N = 2_000.0, 0.25, 5_003
SUFFIX = {"csv": ".csv", "hdf5": ".h5", "tdms": ".tdms", "mdf": ".mf4", "mat73": ".mat",
          "parquet": ".parquet"}
CHUNK = 777  # not a divisor of N, nor of any block size the libraries use


@pytest.fixture(scope="module")
def columns() -> dict[str, np.ndarray]:
    rng = np.random.default_rng(11)
    scale = {"torque_nm": 40.0, "wheel_speed_rad_s": 30.0, "platform_speed_rad_s": 0.7,
             "fx_n": 900.0, "fy_n": 150.0, "fz_n": 4200.0, "vehicle_speed_m_s": 20.0,
             "position_m": 500.0}
    return {c: scale[c] * (1 + 0.1 * rng.standard_normal(N)) for c in CHANNELS}


def _joined(chunks) -> dict[str, np.ndarray]:
    chunks = list(chunks)
    sizes = [next(iter(c.values())).size for c in chunks]
    assert all(s == CHUNK for s in sizes[:-1]) and 0 < sizes[-1] <= CHUNK
    for c in chunks:
        assert all(v.dtype == np.float64 for v in c.values())
    return {k: np.concatenate([c[k] for c in chunks]) for k in chunks[0]}


def _same(path, **kw) -> None:
    rec = read_recording(path, **kw)
    with open_stream(path, **kw) as stream:
        info = stream.info
        got = _joined(stream.chunks(chunk_rows=CHUNK))
    assert set(got) == set(rec.channels)
    for c, x in rec.channels.items():
        np.testing.assert_array_equal(got[c], x, err_msg=c)
    assert info.n_samples == rec.n_samples
    assert info.fs_hz == pytest.approx(rec.fs_hz, rel=1e-12)
    assert info.t0_s == pytest.approx(rec.t0_s, abs=1e-12)


@pytest.mark.parametrize("fmt", list(SUFFIX))
def test_time_column_every_format(fmt, columns, tmp_path, write_columns):
    t = T0_S + np.arange(N) / FS_HZ
    kw = {"fs_hz": FS_HZ, "t0_s": T0_S} if fmt == "mdf" else {}
    cols = dict(columns) if fmt == "mdf" else {"time_s": t, **columns}
    path = write_columns(fmt, tmp_path / f"r{SUFFIX[fmt]}", cols, **kw)
    _same(path)


@pytest.mark.parametrize("fmt", ["hdf5", "tdms", "mat73", "parquet"])
def test_native_sample_rate(fmt, columns, tmp_path, write_columns):
    path = write_columns(fmt, tmp_path / f"r{SUFFIX[fmt]}", dict(columns), fs_hz=FS_HZ,
                         t0_s=T0_S)
    _same(path)


@pytest.mark.parametrize("fmt", ["hdf5", "tdms", "mdf", "parquet"])
def test_units_declared_in_the_file_and_renamed_channels(fmt, columns, tmp_path,
                                                         write_columns):
    """rpm, kN and a mapped name: the stream converts exactly as the whole-file reader."""
    cols = {"Tq": columns["torque_nm"],
            "n_wheel": columns["wheel_speed_rad_s"] * 60 / (2 * np.pi),
            **{c: columns[c] for c in CHANNELS if c not in ("torque_nm", "wheel_speed_rad_s")}}
    cols["fz_n"] = cols["fz_n"] / 1000
    units = {"n_wheel": "rpm", "fz_n": "kN", "Tq": "N*m"}
    path = write_columns(fmt, tmp_path / f"r{SUFFIX[fmt]}", cols, units=units, fs_hz=FS_HZ,
                         t0_s=T0_S)
    cmap = {"torque_nm": "Tq", "wheel_speed_rad_s": "n_wheel"}
    _same(path, channel_map=cmap)
    got = _joined(iter_chunks(path, ["wheel_speed_rad_s", "fz_n"], CHUNK, channel_map=cmap))
    np.testing.assert_allclose(got["wheel_speed_rad_s"], columns["wheel_speed_rad_s"],
                               rtol=1e-12)
    np.testing.assert_allclose(got["fz_n"], columns["fz_n"], rtol=1e-12)


def test_parquet_row_groups_and_csv_blocks_do_not_show(columns, tmp_path, write_columns,
                                                      monkeypatch):
    """Many row groups (Parquet) and many text blocks (CSV) re-cut into equal chunks."""
    import pyarrow as pa
    import pyarrow.parquet as pq
    t = T0_S + np.arange(N) / FS_HZ
    table = pa.table({"time_s": t, **columns})
    path = tmp_path / "groups.parquet"
    pq.write_table(table, path, row_group_size=1000)
    assert pq.ParquetFile(path).num_row_groups == 6
    _same(path)
    from torquemod.io import _stream_tables
    monkeypatch.setattr(_stream_tables, "CSV_BLOCK_BYTES", 10_000)  # ~ 60 rows per text block
    path = write_columns("csv", tmp_path / "blocks.csv", {"time_s": t, **columns})
    _same(path)


def test_manifest_entry_and_sample_rate_override(columns, tmp_path, write_columns):
    path = write_columns("hdf5", tmp_path / "r.h5", dict(columns))  # no time base in file
    entry = RecordingEntry(step=1, dc_torque_nm=10.0, path=path, sample_rate_hz=FS_HZ)
    with open_stream(entry) as stream:
        assert stream.info.fs_hz == FS_HZ
        got = _joined(stream.chunks(["torque_nm"], CHUNK))
    np.testing.assert_array_equal(got["torque_nm"], columns["torque_nm"])


def test_channels_on_different_time_bases_are_refused(columns, tmp_path):
    from nptdms import ChannelObject, GroupObject, TdmsWriter
    path = tmp_path / "offsets.tdms"
    objs = [GroupObject("Meas")]
    for k, (c, v) in enumerate(columns.items()):
        objs.append(ChannelObject("Meas", c, v, properties={
            "wf_increment": 1 / FS_HZ, "wf_start_offset": 0.01 * (k == 1)}))
    with TdmsWriter(str(path)) as w:
        w.write_segment(objs)
    read_recording(path)  # the whole-file reader aligns them
    with pytest.raises(InputError, match="different time bases") as exc:
        open_stream(path)
    assert "offsets.tdms" in str(exc.value)


def test_mat_v5_and_unknown_formats_are_refused(columns, tmp_path, write_columns):
    path = write_columns("mat5", tmp_path / "r.mat", dict(columns), fs_hz=FS_HZ)
    with pytest.raises(InputError, match=r"v7\.3"):
        open_stream(path)
    other = tmp_path / "r.xyz"
    other.write_text("x")
    with pytest.raises(InputError, match="no streaming reader"):
        open_stream(other)


def test_bad_time_column_is_reported_like_the_whole_file_reader(columns, tmp_path,
                                                                write_columns):
    t = T0_S + np.arange(N) / FS_HZ
    t[4000:] += 0.5  # a gap of 1000 periods
    path = write_columns("hdf5", tmp_path / "gap.h5", {"time_s": t, **columns})
    with pytest.raises(InputError) as whole:
        read_recording(path)
    with pytest.raises(InputError) as streamed:
        open_stream(path)
    assert str(streamed.value) == str(whole.value)
    assert "row 4001" in str(streamed.value)


def test_hash_file_async_is_sha256(tmp_path):
    path = tmp_path / "blob.bin"
    data = np.random.default_rng(1).bytes(3 * 2**20 + 17)
    path.write_bytes(data)
    assert hash_file_async(path, block=1 << 20).result() == hashlib.sha256(data).hexdigest()


@pytest.mark.parametrize(("n_rev", "fmt", "chunk"), [(3.6, "hdf5", 997), (3.0, "hdf5", 1 << 14),
                                                     (2.4, "csv", 1500)])
def test_revolutions_streamed_equal_the_whole_file_split(n_rev, fmt, chunk, tmp_path):
    """Index ranges identical to revolution_bounds on the whole platform speed (a wobbling
    speed, chunks that cut revolutions anywhere, a file of exactly whole revolutions), and
    samples identical to Recording.slice."""
    from torquemod.io import write_recording
    from torquemod.processing.cycles import revolution_bounds
    from torquemod.testing import SyntheticSpec, synthetic_recording

    rec = synthetic_recording(SyntheticSpec(fs_hz=FS_HZ, n_revolutions=n_rev, seed=4))
    path = write_recording(tmp_path / f"long.{'h5' if fmt == 'hdf5' else 'csv'}", rec,
                           fmt=fmt)
    whole = read_recording(path)
    bounds = revolution_bounds(whole.channels["platform_speed_rad_s"], whole.fs_hz)
    assert len(bounds) == int(n_rev)
    with open_stream(path) as stream:
        got = list(stream.revolutions(chunk_rows=chunk))
        tail = stream.tail_samples
    assert [r for _, _, r in got] == bounds
    assert [k for k, _, _ in got] == list(range(1, len(bounds) + 1))
    assert tail == whole.n_samples - bounds[-1][1]
    for _, seg, (a, b) in got:
        ref = whole.slice(a, b)
        assert seg.channels.keys() == ref.channels.keys()
        for c in ref.channels:
            np.testing.assert_array_equal(seg.channels[c], ref.channels[c])
        assert seg.t0_s == pytest.approx(ref.t0_s, abs=1e-12)
        assert seg.fs_hz == pytest.approx(ref.fs_hz, rel=1e-12)


def test_last_revolution_completed_within_the_last_sample_interval(tmp_path):
    """A file of exactly 3 revolutions at a constant speed: the angle at the last sample is
    one sample short of 6 pi, so the third revolution is found only at the end of the last
    sample's interval (revolution_bounds' appended point)."""
    from torquemod.io import write_recording
    from torquemod.io.experiment import Recording
    from torquemod.processing.cycles import revolution_bounds

    w = 0.75  # [rad/s]
    n = 3 * 2000  # 3 revolutions of 2000 samples
    fs = n * w / (6 * np.pi)
    rng = np.random.default_rng(2)
    ch = {"torque_nm": rng.standard_normal(n), "wheel_speed_rad_s": 30 + rng.standard_normal(n),
          "platform_speed_rad_s": np.full(n, w)}
    path = write_recording(tmp_path / "exact.h5", Recording(ch, fs, 0.0, "t"), fmt="hdf5")
    whole = read_recording(path)
    bounds = revolution_bounds(whole.channels["platform_speed_rad_s"], whole.fs_hz)
    assert bounds[-1][1] == n and len(bounds) == 3
    with open_stream(path) as stream:
        got = [r for _, _, r in stream.revolutions(chunk_rows=1234)]
        assert stream.tail_samples == 0
    assert got == bounds


def test_hdf5_stream_chunk_cache_by_storage(tmp_path):
    """A streamed HDF5 dataset of unfiltered chunks is opened with no chunk cache (its rows
    are read straight from the file, whatever the chunk size: a cache of one chunk held
    6 x 32 MiB for chunks of 2**22 float64 samples), one of compressed chunks with a cache
    of one chunk (each is decompressed once); a contiguous dataset keeps the default access.
    Every layout reads the same values, also for blocks ending inside chunks."""
    import h5py

    from torquemod.io._stream_tables import _H5Table
    x = np.arange(50_000, dtype=np.float32) * 0.5
    path = tmp_path / "c.h5"
    with h5py.File(path, "w") as fh:
        fh.create_dataset("chunked", data=x, chunks=(3_000,))
        fh.create_dataset("big", data=x.astype(np.float64), chunks=(40_000,))
        fh.create_dataset("gzip", data=x, chunks=(3_000,), compression="gzip", shuffle=True)
        fh.create_dataset("plain", data=x.astype(np.float64))
        default = h5py.h5p.create(h5py.h5p.DATASET_ACCESS).get_chunk_cache()[1]
    table = _H5Table(path, None, mat=False)
    names = ["chunked", "big", "gzip", "plain"]
    try:
        cache = {n: table._dataset(n).id.get_access_plist().get_chunk_cache()[1]
                 for n in names}
        assert cache == {"chunked": 0, "big": 0, "gzip": 3_000 * 4, "plain": default}
        for a, b in ((0, 2_500), (2_500, 9_100), (9_100, 45_000), (45_000, 50_000)):
            got = table.read(names, a, b)
            for n in names:
                np.testing.assert_array_equal(got[n], x[a:b])
    finally:
        table.close()


def test_mdf_stream_reads_record_ranges_not_whole_channels(columns, tmp_path, write_columns,
                                                           monkeypatch):
    """The MDF stream opens the file through a file object, so that asammdf reads a record
    range from the data blocks that hold it. By file name, asammdf 8 reads a channel's whole
    data (``get_channel_raw_bytes_complete``) for every range once the channel group holds
    200 MiB (``validate_blocks``), once per block and channel. That size is faked here and
    the whole-channel read made to fail: the stream does not take it, and its chunks are
    the whole-file values."""
    pytest.importorskip("asammdf")
    from asammdf.blocks import mdf_v4

    def whole_channel(*args, **kwargs):
        raise AssertionError("a record range read the channel's whole data")

    path = write_columns("mdf", tmp_path / "r.mf4", dict(columns), fs_hz=FS_HZ, t0_s=T0_S)
    rec = read_recording(path)  # by name: its whole-channel reads are the fast path
    monkeypatch.setattr(mdf_v4, "validate_blocks", lambda blocks, record_size: True)
    monkeypatch.setattr(mdf_v4, "get_channel_raw_bytes_complete", whole_channel)
    with open_stream(path) as stream:
        got = _joined(stream.chunks(chunk_rows=CHUNK))
        part = stream.read_rows(2_000, 2_100)
    for c, x in rec.channels.items():
        np.testing.assert_array_equal(got[c], x, err_msg=c)
        np.testing.assert_array_equal(part.channels[c], x[2_000:2_100], err_msg=c)


@pytest.mark.parametrize("fmt", ["hdf5", "mat73"])
def test_matrix_mapped_as_a_channel_is_refused_unread(fmt, columns, tmp_path, write_columns,
                                                      monkeypatch):
    """A 2-D dataset (all channels in one matrix) mapped as a channel is refused from its
    shape, before its values are read: read whole first, a long recording's matrix would
    have filled the memory only to be refused."""
    import h5py
    path = write_columns(fmt, tmp_path / f"r{SUFFIX[fmt]}", dict(columns), fs_hz=FS_HZ,
                         t0_s=T0_S)
    with h5py.File(path, "a") as fh:
        fh.create_dataset("block", data=np.zeros((N, 3)))

    real = h5py.Dataset.__getitem__

    def no_read(self, *args, **kwargs):
        if sum(d > 1 for d in self.shape) > 1:
            raise AssertionError("the matrix was read")
        return real(self, *args, **kwargs)

    monkeypatch.setattr(h5py.Dataset, "__getitem__", no_read)
    with pytest.raises(InputError, match=r"'block': expected a 1-D signal, got shape") as e:
        read_recording(path, channel_map={"torque": "block"})
    assert "cannot read" not in str(e.value)


def test_parquet_stream_holds_one_row_group_at_a_time(columns, tmp_path):
    """The Parquet stream reads without pyarrow's pre-buffering, which held the column
    chunks of every row group read so far until the iteration ended (the whole file by
    the end of a long recording). Counted by pyarrow's allocator: while 20 row groups are
    streamed, the live allocations stay under 3 row groups' bytes (without the fix they
    reach the whole file's)."""
    import pyarrow as pa
    import pyarrow.parquet as pq
    rows = 25_000
    rng = np.random.default_rng(4)
    table = pa.table({c: np.repeat(x, 100) + rng.standard_normal(100 * N)
                      for c, x in columns.items() if c in CHANNELS[:6]})
    table = table.slice(0, 20 * rows).replace_schema_metadata({"sample_rate_hz": "1000.0"})
    path = tmp_path / "groups.parquet"
    pq.write_table(table, path, row_group_size=rows, compression="none")
    group_bytes = rows * 6 * 8
    base = pa.total_allocated_bytes()
    peak = 0
    with open_stream(path) as stream:
        for _chunk in stream.chunks(chunk_rows=4_096):
            peak = max(peak, pa.total_allocated_bytes() - base)
    assert 0 < peak < 3 * group_bytes


def test_csv_stream_parses_small_text_blocks(columns, tmp_path, write_columns, monkeypatch):
    """pyarrow's streaming CSV reader keeps about 35 blocks of parsed values alive, so the
    stream asks for blocks of at most 1 MiB of text (4 MiB blocks held ~140 MiB)."""
    from pyarrow import csv as pa_csv

    from torquemod.io import _stream_tables
    t = T0_S + np.arange(N) / FS_HZ
    path = write_columns("csv", tmp_path / "r.csv", {"time_s": t, **columns})
    sizes = []
    real = pa_csv.open_csv

    def spy(*args, **kwargs):
        sizes.append(kwargs["read_options"].block_size)
        return real(*args, **kwargs)

    monkeypatch.setattr(pa_csv, "open_csv", spy)
    _same(path)
    assert sizes and all(s == _stream_tables.CSV_BLOCK_BYTES <= 1 << 20 for s in sizes)
