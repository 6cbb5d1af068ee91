"""CSV recordings: a header row, ``time_s`` plus the method's channels, any column order.

Parsed with pandas' pyarrow engine (multi-threaded C++), not ``np.loadtxt``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from ..data import CHANNELS, Recording
from ..errors import InputError
from .validate import sample_rate_from_time

TIME_COLUMN = "time_s"


def _header(path: Path) -> list[str]:
    try:
        with open(path, encoding="utf-8", errors="replace") as fh:
            line = fh.readline()
    except OSError as exc:
        raise InputError(f"cannot open ({exc.strerror})", path=path) from None
    if not line.strip():
        raise InputError("empty file or empty header row", path=path,
                         hint="the first row must name the columns")
    return [c.strip().strip('"') for c in line.rstrip("\r\n").split(",")]


def read_csv(path: Path, *, group: str | None = None, channel_map: dict | None = None
             ) -> Recording:
    """Read a CSV recording (docs/format.md). ``group`` is not used for CSV."""
    header = _header(path)
    wanted = [TIME_COLUMN, *CHANNELS]
    missing = [c for c in wanted if c not in header]
    if missing:
        raise InputError(f"missing column(s) {', '.join(missing)}", path=path,
                         channel=missing[0],
                         hint=f"the header must contain {', '.join(wanted)}")
    try:
        df = pd.read_csv(path, engine="pyarrow", usecols=wanted)
    except Exception as exc:  # pyarrow raises its own error types for malformed text
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise InputError(f"cannot parse as CSV ({msg})", path=path,
                         hint="check for truncated lines or text in numeric columns") from None
    channels = {}
    for name in wanted:
        col = df[name]
        if not pd.api.types.is_numeric_dtype(col.dtype):
            bad = pd.to_numeric(col, errors="coerce")
            row = int(np.flatnonzero(bad.isna() & col.notna())[0]) if len(col) else 0
            raise InputError(f"non-numeric value {col.iloc[row]!r} at data row {row + 1}",
                             path=path, channel=name, hint="fix or remove that row")
        channels[name] = col.to_numpy(dtype=np.float64, na_value=np.nan)
    if len(df) < 2:
        raise InputError("fewer than two data rows", path=path)
    fs, t0 = sample_rate_from_time(channels.pop(TIME_COLUMN), path=path)
    return Recording(channels, fs, t0, str(path))


def write_csv(path: Path, rec: Recording, *, float_format: str = "%.9g") -> Path:
    """Write ``rec`` as a CSV recording with a ``time_s`` column."""
    data = {TIME_COLUMN: rec.time_s()}
    data.update({k: rec.channels[k] for k in CHANNELS})
    pd.DataFrame(data).to_csv(path, index=False, float_format=float_format)
    return path
