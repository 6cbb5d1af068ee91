"""Ways a user might write one long rig recording, following docs/format.md, for
``benchmarks/memory.py --command ... --layout``.

Each writer takes the folder, the number of samples, the sample type and an iterator of
blocks ``(a, b, t, x)`` (rows ``a:b``, their times [s] and a dict of the six channels in SI
units) and writes the whole recording block by block, so that the writer's own memory stays
small; the file on disk is the one a single call would give (a contiguous HDF5 dataset
written in one go has the same bytes as one written by slices). It returns the file's name
and the manifest's extra keys (``[channels]``), if any.

HDF5 layouts (the project's group layout: one 1-D dataset per channel named as in the CSV
format, a ``unit`` attribute; time base as the group's ``sample_rate_hz`` attribute unless
the layout names a ``time_s`` dataset):

* ``chunk64k``: chunks of 65 536 samples (what the benchmark always wrote);
* ``contiguous``: no chunks (h5py's default for ``create_dataset(name, data=array)``);
* ``contiguous-time``: the same with a float64 ``time_s`` dataset and no rate attribute;
* ``auto``: ``chunks=True`` (h5py picks the chunk shape, ~8k samples for these lengths);
* ``resizable``: ``maxshape=(None,)`` with h5py's chunks, grown block by block (a logger
  appending);
* ``chunk1m``, ``chunk4m``: chunks of 2**20 and 2**22 samples;
* ``gzip``, ``gzip1m``, ``gzip4m``: gzip level 4 with the shuffle filter, on h5py's chunks,
  2**20 and 2**22 samples;
* ``mat73``: a MATLAB v7.3 file (HDF5 with the 512-byte MATLAB header, each channel an
  n-by-1 double stored as a 1-by-n dataset, deflate-compressed chunks as MATLAB writes them,
  and a scalar ``sample_rate_hz`` variable).

Other formats: ``tdms`` (nptdms, one segment per block, waveform properties), ``mdf4``
(asammdf, one channel group, its master the time stamps, extended block by block),
``parquet`` (pyarrow, one row group per block, ``sample_rate_hz`` key-value metadata) and
``csv`` (pyarrow's writer: a ``time_s`` column, the shortest text that reads back each
value).
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np

RIG_CHANNELS = ("torque_nm", "wheel_speed_rad_s", "platform_speed_rad_s", "fx_n", "fy_n",
                "fz_n")
UNITS = {"torque_nm": "N*m", "wheel_speed_rad_s": "rad/s", "platform_speed_rad_s": "rad/s",
         "fx_n": "N", "fy_n": "N", "fz_n": "N", "time_s": "s"}

HDF5_LAYOUTS = {
    # name: (create_dataset keywords, time_s dataset, resizable)
    "chunk64k": ({"chunks": (1 << 16,)}, False, False),
    "contiguous": ({}, False, False),
    "contiguous-time": ({}, True, False),
    "auto": ({"chunks": True}, False, False),
    "resizable": ({"chunks": True}, False, True),
    "chunk1m": ({"chunks": (1 << 20,)}, False, False),
    "chunk4m": ({"chunks": (1 << 22,)}, False, False),
    "gzip": ({"chunks": True, "compression": "gzip", "compression_opts": 4,
              "shuffle": True}, False, False),
    "gzip1m": ({"chunks": (1 << 20,), "compression": "gzip", "compression_opts": 4,
                "shuffle": True}, False, False),
    "gzip4m": ({"chunks": (1 << 22,), "compression": "gzip", "compression_opts": 4,
                "shuffle": True}, False, False),
}
OTHER_LAYOUTS = ("mat73", "tdms", "mdf4", "parquet", "csv")
LAYOUTS = (*HDF5_LAYOUTS, *OTHER_LAYOUTS)

Blocks = Iterator[tuple[int, int, np.ndarray, dict]]


def rig_blocks(n_total: int, fs_hz: float, block_s: float = 60.0) -> Blocks:
    """``(a, b, t, x)`` for rows ``a:b`` of the long recording: times [s] and the six
    channels (float64, SI units), ``block_s`` at a time: the platform and wheel at the
    default synthetic speeds with 1x/2x encoder eccentricity, a 2 Hz torque modulation
    answered 20 deg later by the wheel speed, constant forces, white noise (levels of
    :class:`torquemod.testing.SyntheticSpec`; ``benchmarks/memory.py --command``)."""
    from torquemod.testing import SyntheticSpec

    sp = SyntheticSpec(fs_hz=fs_hz)
    rng = np.random.default_rng(5)
    wp, ww = sp.platform_speed_rad_s, sp.wheel_speed_rad_s
    w_mod = 2 * np.pi * sp.modulation_hz
    lag = np.deg2rad(sp.phase_lag_deg)
    step = round(block_s * fs_hz)
    for a in range(0, n_total, step):
        b = min(n_total, a + step)
        t = np.arange(a, b) / fs_hz
        m = b - a
        ecc_p = 1 + 5e-3 * np.cos(wp * t) + 2e-3 * np.cos(2 * wp * t + 1.0)
        ecc_w = 1 + 7e-3 * np.cos(ww * t) + 3e-3 * np.cos(2 * ww * t + 0.5)
        x = {"platform_speed_rad_s": wp * ecc_p
             + sp.platform_noise_rad_s * rng.standard_normal(m),
             "wheel_speed_rad_s": (ww + sp.wheel_mod_amplitude_rad_s
                                   * np.sin(w_mod * t + sp.modulation_phase_rad - lag))
             * ecc_w + sp.wheel_noise_rad_s * rng.standard_normal(m),
             "torque_nm": sp.dc_torque_nm + sp.modulation_amplitude_nm
             * np.sin(w_mod * t + sp.modulation_phase_rad)
             + sp.torque_noise_nm * rng.standard_normal(m),
             "fx_n": sp.dc_torque_nm / sp.wheel_radius_m
             + sp.force_noise_n * rng.standard_normal(m),
             "fy_n": sp.lateral_force_n + sp.force_noise_n * rng.standard_normal(m),
             "fz_n": sp.normal_load_n + sp.force_noise_n * rng.standard_normal(m)}
        yield a, b, t, x


def write(layout: str, folder: Path, n_total: int, fs_hz: float, dtype: str,
          blocks: Blocks) -> tuple[str, dict]:
    """Write the recording in ``layout``; (file name, [channels] table or {})."""
    if layout in HDF5_LAYOUTS:
        return _hdf5(layout, folder, n_total, fs_hz, dtype, blocks), {}
    return {"mat73": _mat73, "tdms": _tdms, "mdf4": _mdf4, "parquet": _parquet,
            "csv": _csv}[layout](folder, n_total, fs_hz, dtype, blocks)


def _hdf5(layout: str, folder: Path, n_total: int, fs_hz: float, dtype: str,
          blocks: Blocks) -> str:
    import h5py

    kw, with_time, resizable = HDF5_LAYOUTS[layout]
    names = (["time_s"] if with_time else []) + list(RIG_CHANNELS)
    with h5py.File(folder / "long.h5", "w") as fh:
        fh.attrs["torquemod_layout"] = 1
        if not with_time:
            fh.attrs["sample_rate_hz"] = fs_hz
            fh.attrs["t0_s"] = 0.0
        if isinstance(kw.get("chunks"), tuple):  # no longer than a short recording
            kw = {**kw, "chunks": (min(kw["chunks"][0], n_total),)}
        ds = {}
        for c in names:
            shape, maxshape = ((0,), (None,)) if resizable else ((n_total,), None)
            ds[c] = fh.create_dataset(c, shape=shape, maxshape=maxshape,
                                      dtype="f8" if c == "time_s" else dtype, **kw)
            ds[c].attrs["unit"] = UNITS[c]
        for a, b, t, x in blocks:
            for c in names:
                if resizable:
                    ds[c].resize((b,))
                ds[c][a:b] = t if c == "time_s" else x[c]
    return "long.h5"


def _mat73(folder: Path, n_total: int, fs_hz: float, dtype: str, blocks: Blocks
           ) -> tuple[str, dict]:
    import h5py

    cls = "double" if dtype == "f8" else "single"
    path = folder / "long.mat"
    with h5py.File(path, "w", userblock_size=512) as fh:
        ds = {}
        for c in RIG_CHANNELS:
            ds[c] = fh.create_dataset(c, shape=(1, n_total), dtype=dtype, chunks=True,
                                      compression="gzip", compression_opts=3)
            ds[c].attrs["MATLAB_class"] = np.bytes_(cls)
        fs = fh.create_dataset("sample_rate_hz", data=np.array([[fs_hz]]))
        fs.attrs["MATLAB_class"] = np.bytes_("double")
        for a, b, _t, x in blocks:
            for c in RIG_CHANNELS:
                ds[c][0, a:b] = x[c]
    head = b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Fri Nov 27 00:00:00 2026 " \
           b"HDF5 schema 1.00 ."
    with open(path, "r+b") as fh:
        fh.write(head.ljust(116, b" ") + b"\x00" * 8 + b"\x00\x02IM")
    return "long.mat", {}


def _tdms(folder: Path, n_total: int, fs_hz: float, dtype: str, blocks: Blocks
          ) -> tuple[str, dict]:
    from nptdms import ChannelObject, TdmsWriter

    with TdmsWriter(folder / "long.tdms") as w:
        for _a, _b, _t, x in blocks:
            w.write_segment([ChannelObject("Rig", c, np.asarray(x[c], dtype=dtype),
                                           properties={"unit_string": UNITS[c],
                                                       "wf_increment": 1.0 / fs_hz,
                                                       "wf_start_offset": 0.0})
                             for c in RIG_CHANNELS])
    return "long.tdms", {"channels": {c: f"Rig/{c}" for c in RIG_CHANNELS}}


def _mdf4(folder: Path, n_total: int, fs_hz: float, dtype: str, blocks: Blocks
          ) -> tuple[str, dict]:
    from asammdf import MDF, Signal

    mdf = MDF(version="4.10")
    for a, _b, t, x in blocks:
        if a == 0:
            mdf.append([Signal(np.asarray(x[c], dtype=dtype), t, name=c, unit=UNITS[c])
                        for c in RIG_CHANNELS])
        else:
            mdf.extend(0, [(t, None), *((np.asarray(x[c], dtype=dtype), None)
                                        for c in RIG_CHANNELS)])
    mdf.save(folder / "long.mf4", overwrite=True)
    mdf.close()
    return "long.mf4", {}


def _parquet(folder: Path, n_total: int, fs_hz: float, dtype: str, blocks: Blocks
             ) -> tuple[str, dict]:
    import pyarrow as pa
    import pyarrow.parquet as pq

    typ = pa.float64() if dtype == "f8" else pa.float32()
    schema = pa.schema([pa.field(c, typ, metadata={"unit": UNITS[c]}) for c in RIG_CHANNELS],
                       metadata={"sample_rate_hz": repr(fs_hz), "t0_s": "0.0"})
    with pq.ParquetWriter(folder / "long.parquet", schema) as w:
        for _a, _b, _t, x in blocks:
            w.write_table(pa.table({c: np.asarray(x[c], dtype=dtype) for c in RIG_CHANNELS},
                                   schema=schema))
    return "long.parquet", {}


def _csv(folder: Path, n_total: int, fs_hz: float, dtype: str, blocks: Blocks
         ) -> tuple[str, dict]:
    import pyarrow as pa
    from pyarrow import csv as pa_csv

    typ = pa.float64() if dtype == "f8" else pa.float32()
    schema = pa.schema([pa.field("time_s", pa.float64()),
                        *(pa.field(c, typ) for c in RIG_CHANNELS)])
    with pa_csv.CSVWriter(folder / "long.csv", schema,
                          write_options=pa_csv.WriteOptions(quoting_style="none")) as w:
        for _a, _b, t, x in blocks:
            w.write_table(pa.table({"time_s": t, **{c: np.asarray(x[c], dtype=dtype)
                                                    for c in RIG_CHANNELS}}, schema=schema))
    return "long.csv", {}
