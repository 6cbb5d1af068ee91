"""Shared fixtures."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

#: Formats the recording writers below produce, with their file suffix.
FORMAT_SUFFIX = {"csv": ".csv", "hdf5": ".h5", "tdms": ".tdms", "mdf": ".mf4", "mat5": ".mat",
                 "mat73": ".mat", "parquet": ".parquet"}

_MAT73_HEADER = b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Mon Jan  1 00:00:00 2024 HDF5 schema 1.00 ."  # noqa: E501


def _nest(columns: dict[str, np.ndarray]) -> dict:
    """``{"a.b": x}`` as ``{"a": {"b": x}}`` (MATLAB structs)."""
    out: dict = {}
    for name, values in columns.items():
        node = out
        *parents, leaf = name.split(".")
        for p in parents:
            node = node.setdefault(p, {})
        node[leaf] = values
    return out


def write_columns(fmt: str, path: Path, columns: dict[str, np.ndarray], *,
                  units: dict[str, str] | None = None, fs_hz: float | None = None,
                  t0_s: float = 0.0) -> Path:
    """Write ``columns`` (file channel name -> values) as a recording in ``fmt`` with the
    format's own library. ``units`` go where the format keeps units; ``fs_hz`` [Hz] becomes
    the format's own sample rate (TDMS wf_increment, MDF time stamps, .mat ``fs``, HDF5 and
    Parquet attributes). TDMS names may be "Group/Channel" (bare names go to group "Meas");
    .mat names may be "struct.field"."""
    path = Path(path)
    units = units or {}
    n = len(next(iter(columns.values())))
    if fmt == "csv":
        import pandas as pd
        pd.DataFrame(columns).to_csv(path, index=False, float_format="%.17g")
    elif fmt == "hdf5":
        import h5py
        with h5py.File(path, "w") as fh:
            for name, values in columns.items():
                ds = fh.create_dataset(name, data=values)
                if name in units:
                    ds.attrs["unit"] = units[name]
            if fs_hz is not None:
                fh.attrs["sample_rate_hz"] = fs_hz
                fh.attrs["t0_s"] = t0_s
    elif fmt == "tdms":
        from nptdms import ChannelObject, GroupObject, TdmsWriter
        objects, groups = [], {}
        for name, values in columns.items():
            group, _, channel = name.rpartition("/")
            group = group or "Meas"
            groups[group] = GroupObject(group)
            props = {}
            if name in units:
                props["unit_string"] = units[name]
            if fs_hz is not None:
                props["wf_increment"] = 1.0 / fs_hz
                props["wf_start_offset"] = t0_s
            objects.append(ChannelObject(group, channel, np.asarray(values), properties=props))
        with TdmsWriter(str(path)) as writer:
            writer.write_segment([*groups.values(), *objects])
    elif fmt == "mdf":
        from asammdf import MDF, Signal
        if fs_hz is None:
            raise ValueError("MDF needs fs_hz for its master channel")
        t = t0_s + np.arange(n) / fs_hz
        mdf = MDF(version="4.10")
        mdf.append([Signal(np.asarray(v), t, name=k, unit=units.get(k, ""))
                    for k, v in columns.items()])
        mdf.save(path, overwrite=True)
        mdf.close()
    elif fmt == "mat5":
        import scipy.io
        doc = _nest({k: np.asarray(v).reshape(-1, 1) for k, v in columns.items()})
        if fs_hz is not None:
            doc["fs"] = fs_hz
            doc["t0_s"] = t0_s
        scipy.io.savemat(path, doc)
    elif fmt == "mat73":
        import h5py
        with h5py.File(path, "w", userblock_size=512) as fh:
            for name, values in columns.items():
                ds = fh.create_dataset(name.replace(".", "/"),
                                       data=np.asarray(values).reshape(1, -1))
                ds.attrs["MATLAB_class"] = np.bytes_("double")
            if fs_hz is not None:
                for key, value in (("fs", fs_hz), ("t0_s", t0_s)):
                    fh.create_dataset(key, data=np.array([[value]]))
                    fh[key].attrs["MATLAB_class"] = np.bytes_("double")
        with open(path, "r+b") as fh:
            fh.write(_MAT73_HEADER.ljust(116) + b"\0" * 8 + b"\x00\x02IM")
    elif fmt == "parquet":
        import pyarrow as pa
        import pyarrow.parquet as pq
        fields = [pa.field(k, pa.float64(),
                           metadata={"unit": units[k]} if k in units else None)
                  for k in columns]
        meta = {"sample_rate_hz": repr(fs_hz), "t0_s": repr(t0_s)} if fs_hz else None
        table = pa.table({k: np.asarray(v, dtype=np.float64) for k, v in columns.items()},
                         schema=pa.schema(fields, metadata=meta))
        pq.write_table(table, path)
    else:
        raise ValueError(fmt)
    return path


@pytest.fixture(name="write_columns", scope="session")
def _write_columns_fixture():
    """The :func:`write_columns` helper: write a recording in any supported format."""
    return write_columns
