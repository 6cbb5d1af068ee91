"""The project's HDF5 layout (docs/format.md).

A recording is an HDF5 group (the file's root unless the manifest names ``group``) holding one
1-D float64 dataset per channel, named as in the CSV format (``torque_nm``, ...), and either a
``time_s`` dataset or a ``sample_rate_hz`` attribute on the group (with optional ``t0_s``).
Each dataset carries a ``unit`` attribute. One file may hold a whole experiment, one group per
recording.
"""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np

from ..data import CHANNEL_UNITS, CHANNELS, Recording
from ..errors import InputError
from .validate import sample_rate_from_time

LAYOUT_VERSION = 1


def read_hdf5(path: Path, *, group: str | None = None, channel_map: dict | None = None
              ) -> Recording:
    """Read one recording group of the project's HDF5 layout."""
    try:
        fh = h5py.File(path, "r")
    except OSError as exc:
        raise InputError(f"cannot open as HDF5 ({exc})", path=path,
                         hint="is the file complete and really HDF5?") from None
    with fh:
        where = group or "/"
        if where not in fh:
            raise InputError(f"no group '{where}' in the file", path=path,
                             hint="check the 'group' entry in the manifest")
        g = fh[where]
        if not isinstance(g, h5py.Group):
            raise InputError(f"'{where}' is a dataset, not a group", path=path)
        channels = {}
        for name in CHANNELS:
            if name not in g:
                raise InputError(f"missing dataset in group '{where}'", path=path, channel=name,
                                 hint=f"the group must hold {', '.join(CHANNELS)}")
            try:
                channels[name] = np.asarray(g[name][()], dtype=np.float64).reshape(-1)
            except (OSError, ValueError, TypeError) as exc:
                raise InputError(f"cannot read dataset ({exc})", path=path, channel=name) from None
        if "time_s" in g:
            fs, t0 = sample_rate_from_time(np.asarray(g["time_s"][()], dtype=np.float64),
                                           path=f"{path}:{where}")
        elif "sample_rate_hz" in g.attrs:
            fs = float(g.attrs["sample_rate_hz"])
            t0 = float(g.attrs.get("t0_s", 0.0))
            if not np.isfinite(fs) or fs <= 0:
                raise InputError(f"attribute sample_rate_hz={fs} is not a positive number",
                                 path=path)
        else:
            raise InputError(f"group '{where}' has neither a time_s dataset nor a "
                             "sample_rate_hz attribute", path=path, channel="time_s")
    return Recording(channels, fs, t0, f"{path}" + (f":{group}" if group else ""))


def write_hdf5(path: Path, rec: Recording, *, group: str | None = None,
               write_time: bool = False, compression: str | None = None,
               attrs: dict | None = None) -> Path:
    """Write ``rec`` into ``group`` (root by default) of ``path`` (appending to the file).

    The sample rate goes into the ``sample_rate_hz`` attribute; ``write_time`` also writes
    the ``time_s`` dataset.
    """
    with h5py.File(path, "a") as fh:
        g = fh.require_group(group) if group else fh
        g.attrs["torquemod_layout"] = LAYOUT_VERSION
        g.attrs["sample_rate_hz"] = float(rec.fs_hz)
        g.attrs["t0_s"] = float(rec.t0_s)
        for k, v in (attrs or {}).items():
            g.attrs[k] = v
        names = (["time_s"] if write_time else []) + list(CHANNELS)
        for name in names:
            data = rec.time_s() if name == "time_s" else rec.channels[name]
            if name in g:
                del g[name]
            ds = g.create_dataset(name, data=np.asarray(data, dtype=np.float64),
                                  compression=compression)
            ds.attrs["unit"] = CHANNEL_UNITS[name]
    return path
