"""Parquet recordings: one numeric column per channel, named as in the CSV format or mapped
in the manifest's ``[channels]`` table, read with ``pyarrow``.

Units come from the manifest, else from a ``unit`` entry in the column's field metadata.
Without a time column the sample rate comes from the file's key-value metadata
``sample_rate_hz`` [Hz] (with optional ``t0_s`` [s]).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from torquemod.errors import InputError
from torquemod.io.channels import (
    ChannelMap,
    RawChannel,
    library_error,
    resolve_channel_map,
)
from torquemod.io.experiment import Recording
from torquemod.io.timebase import assemble_recording

_HINT = "is the file complete and really Parquet?"


def _meta_text(meta: dict | None, key: str) -> str | None:
    if not meta or key.encode() not in meta:
        return None
    return meta[key.encode()].decode("utf-8", errors="replace")


def _native_rate(meta: dict | None, path: Path) -> tuple[float, float] | None:
    text = _meta_text(meta, "sample_rate_hz")
    if text is None:
        return None
    try:
        fs = float(text)
        t0 = float(_meta_text(meta, "t0_s") or 0.0)
    except ValueError:
        raise InputError(f"metadata sample_rate_hz={text!r} is not a number", path=path,
                         hint="write the sample rate in Hz") from None
    if not math.isfinite(fs) or fs <= 0 or not math.isfinite(t0):
        raise InputError(f"metadata sample_rate_hz={text!r} is not a positive number",
                         path=path)
    return fs, t0


def _column_values(column: pa.ChunkedArray, path: Path, name: str) -> np.ndarray:
    kind = column.type
    if not (pa.types.is_integer(kind) or pa.types.is_floating(kind)
            or pa.types.is_boolean(kind) or pa.types.is_timestamp(kind)
            or pa.types.is_duration(kind)):
        raise InputError(f"column '{name}' is not numeric (type {kind})", path=path,
                         hint="map a numeric column")
    if column.null_count:  # nulls become NaN (the NaN policy is the pipeline's)
        column = column.cast(pa.float64()) if not pa.types.is_temporal(kind) else column
    return np.asarray(column.to_numpy())


def read_parquet(path: Path, *, group: str | None = None,
                 channel_map: ChannelMap | dict | None = None) -> Recording:
    """Read a Parquet recording.

    Parameters
    ----------
    path : pathlib.Path
        The Parquet file.
    group : str or None
        Must be None (no groups in Parquet).
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
        A ``group`` given, the file cannot be opened or read as Parquet, or a column cannot
        be converted; the message names the file and, where one is at fault, the channel.
    """
    path = Path(path)
    cmap = resolve_channel_map(channel_map, path)
    if group is not None:
        raise InputError(f"'group' ({group!r}) has no meaning for a Parquet file", path=path,
                         hint="remove 'group' from the recording's entry")
    try:
        schema = pq.read_schema(path)
        names = list(schema.names)
    except Exception as exc:  # pyarrow raises ArrowInvalid/OSError on damaged files
        raise library_error(exc, path=path, what="cannot open as Parquet", hint=_HINT) from None
    wanted = [n for n in dict.fromkeys([*cmap.names(), cmap.time.name,
                                        *cmap.own_time_names()]) if n in names]
    try:
        table = pq.read_table(path, columns=wanted)
    except Exception as exc:  # damaged pages, bad compression, ...
        raise library_error(exc, path=path, what="cannot read the Parquet data",
                            hint=_HINT) from None

    def lookup(name: str) -> RawChannel | None:
        if name not in table.column_names:
            return None
        field = table.schema.field(name)
        try:
            values = _column_values(table.column(name), path, name)
        except InputError:
            raise
        except Exception as exc:  # pyarrow conversion of damaged or odd columns
            raise library_error(exc, path=path, what=f"cannot convert column '{name}'",
                                hint=_HINT) from None
        return RawChannel(values, _meta_text(field.metadata, "unit"))

    return assemble_recording(cmap, lookup, path=path, source=str(path),
                              native_rate=_native_rate(schema.metadata, path),
                              available=lambda: names)


def write_parquet(path: Path, rec: Recording) -> Path:
    """Write a Parquet recording.

    One float64 column per channel ``rec`` has (SI units, each column's ``unit`` in its field
    metadata) and ``sample_rate_hz`` [Hz] and ``t0_s`` [s] in the file's metadata, so it
    reads back exactly without a ``[channels]`` table.

    Parameters
    ----------
    path : pathlib.Path
        The file to write.
    rec : Recording
        The recording.

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    InputError
        The file cannot be written.
    """
    from torquemod.io.experiment import CHANNEL_UNITS, CHANNELS
    fields, arrays = [], []
    for name in CHANNELS:
        if name in rec.channels:
            fields.append(pa.field(name, pa.float64(),
                                   metadata={b"unit": CHANNEL_UNITS[name].encode()}))
            arrays.append(pa.array(np.asarray(rec.channels[name], dtype=np.float64)))
    meta = {b"sample_rate_hz": repr(float(rec.fs_hz)).encode(),
            b"t0_s": repr(float(rec.t0_s)).encode()}
    table = pa.Table.from_arrays(arrays, schema=pa.schema(fields, metadata=meta))
    try:
        pq.write_table(table, path)
    except OSError as exc:
        raise InputError(f"cannot write ({exc})", path=path) from None
    return path
