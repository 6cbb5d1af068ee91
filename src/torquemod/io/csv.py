"""CSV recordings: a header row, ``time_s`` plus the method's channels, any column order.

Column names and units can be mapped with the manifest's ``[channels]`` table
(:mod:`torquemod.io.channels`). Parsed with pandas' pyarrow engine (multi-threaded C++), not
``np.loadtxt``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pyarrow as pa
from pyarrow import csv as pa_csv

from torquemod.errors import InputError
from torquemod.io.channels import (
    TIME,
    ChannelMap,
    RawChannel,
    library_error,
    resolve_channel_map,
)
from torquemod.io.experiment import CHANNELS, OPTIONAL_CHANNELS, Recording
from torquemod.io.timebase import assemble_recording

TIME_COLUMN = TIME


def _header(path: Path) -> list[str]:
    try:
        with open(path, encoding="utf-8-sig", errors="replace") as fh:
            line = fh.readline()
    except OSError as exc:
        raise InputError(f"cannot open ({exc.strerror})", path=path) from None
    if not line.strip():
        raise InputError("empty file or empty header row", path=path,
                         hint="the first row must name the columns")
    return [c.strip().strip('"') for c in line.rstrip("\r\n").split(",")]


def read_csv(path: Path, *, group: str | None = None,
             channel_map: ChannelMap | dict | None = None) -> Recording:
    """Read a CSV recording (docs/format.md).

    Parameters
    ----------
    path : pathlib.Path
        The CSV file.
    group : str or None
        Not used for CSV.
    channel_map : ChannelMap or dict or None
        The manifest's ``[channels]`` table (raw or resolved,
        :func:`~torquemod.io.channels.resolve_channel_map`); None reads the method's channel
        names (:data:`~torquemod.io.experiment.CHANNELS`) in SI units.

    Returns
    -------
    Recording
        The channels in SI units on a uniform time base (NaN and inf are not checked here:
        the NaN policy is the pipeline's).

    Raises
    ------
    InputError
        Duplicate or missing columns, fewer than two data rows, a non-numeric value, a file
        separated otherwise than by commas, or a file the parser cannot read; the message
        names the file and, where one is at fault, the channel.
    """
    path = Path(path)
    cmap = resolve_channel_map(channel_map, path)
    header = _header(path)
    by_name = {cmap.spec(c).name: c for c in CHANNELS}
    if cmap.sample_rate_hz is None:
        by_name.setdefault(cmap.time.name, TIME)
    for c in CHANNELS:  # the channels' own time columns ([channels] entry key 'time')
        if cmap.spec(c).time:
            by_name.setdefault(cmap.spec(c).time, c)
    wanted = list(by_name)
    twice = [n for n in wanted if header.count(n) > 1]
    if twice:
        raise InputError(f"column(s) {', '.join(twice)} appear more than once in the header",
                         path=path, channel=by_name[twice[0]],
                         hint="rename or remove the duplicate columns")
    optional = {cmap.spec(c).name for c in OPTIONAL_CHANNELS if not cmap.spec(c).explicit}
    missing = [n for n in wanted if n not in header]
    if missing and len(header) == 1:
        for sep, word in ((";", "';'"), ("\t", "tabs"), ("|", "'|'"), (" ", "spaces")):
            if sep in header[0].strip():
                raise InputError(f"the header row has one column; the file seems separated by "
                                 f"{word}", path=path, hint="torquemod reads comma-separated "
                                 "files with '.' as decimal point; convert the file")
    wanted = [n for n in wanted if n in header or n not in optional]
    missing = [n for n in missing if n not in optional]
    if missing:
        rate = (" (or set sample_rate_hz instead of a time column)"
                if TIME in map(by_name.get, missing) else "")
        raise InputError(f"missing column(s) {', '.join(missing)}", path=path,
                         channel=by_name[missing[0]],
                         hint=f"the header must contain {', '.join(wanted)}, or map the "
                              f"columns in the manifest's [channels]{rate}")
    try:
        # single-threaded parse: the pipeline already reads recordings in parallel threads
        table = pa_csv.read_csv(
            path, read_options=pa_csv.ReadOptions(use_threads=False, block_size=1 << 24),
            convert_options=pa_csv.ConvertOptions(include_columns=wanted))
    except Exception as exc:  # pyarrow raises its own error types for malformed text
        raise library_error(exc, path=path, what="cannot parse as CSV",
                            hint="check for truncated lines or text in numeric columns"
                            ) from None
    if table.num_rows < 2:
        raise InputError("fewer than two data rows", path=path,
                         hint="the file holds no recording; export the data again")

    def lookup(name: str) -> RawChannel | None:
        if name not in table.column_names:
            return None
        col = table.column(name)
        if not (pa.types.is_floating(col.type) or pa.types.is_integer(col.type)
                or pa.types.is_null(col.type)):
            values = col.to_pylist()
            import pandas as pd  # only for the error message; pandas is slow to import
            bad = pd.to_numeric(pd.Series(values), errors="coerce")
            rows = np.flatnonzero(bad.isna().to_numpy() & pd.Series(values).notna().to_numpy())
            row = int(rows[0]) if rows.size else 0
            raise InputError(f"non-numeric value {values[row]!r} at data row {row + 1}",
                             path=path, channel=by_name.get(name, name),
                             hint="fix or remove that row")
        return RawChannel(col.to_numpy(zero_copy_only=False).astype(np.float64, copy=False))

    return assemble_recording(cmap, lookup, path=path, source=str(path),
                              available=lambda: header)


def _round_significant(x: np.ndarray, digits: int) -> np.ndarray:
    """``x`` rounded to ``digits`` significant digits of its largest magnitude (one decimal
    position for the whole column, so the sample spacing of a time column stays uniform)."""
    peak = float(np.max(np.abs(x))) if x.size else 0.0
    if peak == 0.0 or not np.isfinite(peak):
        return x
    return np.round(x, digits - 1 - int(np.floor(np.log10(peak))))


def write_csv(path: Path, rec: Recording, *, significant_digits: int = 9) -> Path:
    """Write a CSV recording.

    A ``time_s`` column [s] and the channels ``rec`` has (absent optional channels are left
    out), each column rounded to ``significant_digits`` (pyarrow prints the shortest decimal
    that reads back exactly).

    Parameters
    ----------
    path : pathlib.Path
        The file to write.
    rec : Recording
        The recording.
    significant_digits : int
        Significant digits per value [-]. Default 9.

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    InputError
        The file cannot be written.
    """
    data = {TIME_COLUMN: rec.time_s()}
    data.update({k: rec.channels[k] for k in CHANNELS if k in rec.channels})
    table = pa.table({k: _round_significant(np.asarray(v, dtype=np.float64), significant_digits)
                      for k, v in data.items()})
    try:
        pa_csv.write_csv(table, path, write_options=pa_csv.WriteOptions(
            quoting_style="none", quoting_header="none", batch_size=1 << 16))
    except OSError as exc:
        raise InputError(f"cannot write ({exc})", path=path) from None
    return path
