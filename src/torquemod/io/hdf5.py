"""The project's HDF5 layout (docs/format.md).

A recording is an HDF5 group (the file's root unless the manifest names ``group``) holding one
1-D float64 dataset per channel, named as in the CSV format (``torque_nm``, ...), and either a
``time_s`` dataset or a ``sample_rate_hz`` attribute on the group (with optional ``t0_s``).
Each dataset carries a ``unit`` attribute (honoured when reading). One file may hold a whole
experiment, one group per recording. Other layouts are read through the manifest's
``[channels]`` table, whose names may be paths below the group (``"daq/torque"``). Integer
datasets with the CF attributes ``scale_factor``/``add_offset`` (a logger's raw counts) are
read as ``counts * scale_factor + add_offset``. The group attribute ``torquemod_notes`` (what
an earlier read did to the channels, written by ``torquemod convert``) is carried into the
recording's notes.
"""

from __future__ import annotations

import functools
import os
from pathlib import Path

import h5py
import numpy as np
from h5py import h5a, h5d, h5f, h5g, h5p, h5s, h5t

from torquemod.errors import InputError
from torquemod.io.channels import (
    ChannelMap,
    RawChannel,
    library_error,
    resolve_channel_map,
    source_name,
)
from torquemod.io.experiment import CHANNEL_UNITS, CHANNELS, Recording
from torquemod.io.timebase import assemble_recording

LAYOUT_VERSION = 1
#: Group attribute holding the notes of the recording the file was written from.
NOTES_ATTR = "torquemod_notes"


def _attr_text(value: object) -> str | None:
    if isinstance(value, bytes):
        return value.decode("utf-8", errors="replace")
    if isinstance(value, np.ndarray) and value.size == 1:
        return _attr_text(value.reshape(-1)[0])
    return value if isinstance(value, str) else None


def _group_rate(g: h5py.Group, path: Path) -> tuple[float, float] | None:
    try:
        if "sample_rate_hz" not in g.attrs:
            return None
        fs = float(np.asarray(g.attrs["sample_rate_hz"]).reshape(-1)[0])
        t0 = float(np.asarray(g.attrs.get("t0_s", 0.0)).reshape(-1)[0])
    except Exception as exc:  # h5py/numpy on an unreadable or non-numeric attribute
        raise library_error(exc, path=path, what="cannot read attribute sample_rate_hz",
                            hint="it must be a number [Hz]") from None
    if not np.isfinite(fs) or fs <= 0:
        raise InputError(f"attribute sample_rate_hz={fs} is not a positive number",
                         path=path)
    return fs, t0


def _dataset(g: h5py.Group, name: str, path: Path, *, unit_attr: str = "unit"
             ) -> RawChannel | None:
    """The dataset ``name`` (a path below ``g``) as a :class:`RawChannel`, None if absent."""
    try:
        obj = g.get(name)
        if obj is None:
            return None
        if not isinstance(obj, h5py.Dataset):
            raise InputError(f"'{name}' is a group, not a dataset", path=path,
                             hint="map a dataset in [channels]")
        if sum(d > 1 for d in obj.shape) > 1:  # refused before its values are read
            raise InputError(f"dataset '{name}': expected a 1-D signal, got shape "
                             f"{obj.shape}", path=path,
                             hint="map a vector (one value per sample)")
        values = np.asarray(obj[()])
        unit = _attr_text(obj.attrs.get(unit_attr)) if unit_attr in obj.attrs else None
        scale = [_attr_number(obj, key, name, path) for key in ("scale_factor", "add_offset")]
    except InputError:
        raise
    except Exception as exc:  # h5py raises OSError/KeyError/ValueError... on damaged files
        raise library_error(exc, path=path, what=f"cannot read dataset '{name}'",
                            hint="is the file complete?") from None
    if scale != [None, None] and values.dtype.kind in "biuf":
        values = values.astype(np.float64)  # counts -> values in the dataset's unit
        if scale[0] is not None:
            values *= scale[0]
        if scale[1] is not None:
            values += scale[1]
    return RawChannel(values, unit)


def _attr_number(obj: h5py.Dataset, key: str, name: str, path: Path) -> float | None:
    if key not in obj.attrs:
        return None
    value = np.asarray(obj.attrs[key])
    if value.size != 1 or value.dtype.kind not in "biuf" or \
            not np.isfinite(float(value.reshape(-1)[0])):
        raise InputError(f"dataset '{name}': attribute {key}={value!r} is not a finite number",
                         path=path, hint="repair the attribute or remove it")
    return float(value.reshape(-1)[0])


def _notes(g: h5py.Group) -> list[str]:
    try:
        value = g.attrs.get(NOTES_ATTR)
        if value is None:
            return []
        items = np.asarray(value).reshape(-1).tolist()
    except Exception:  # a damaged attribute: the notes are provenance only
        return ["the file's torquemod_notes attribute could not be read"]
    texts = [_attr_text(v) for v in items]
    return [f"as written to the file: {t}" for t in texts if t]


def _names(g: h5py.Group) -> list[str]:
    out: list[str] = []
    try:
        g.visititems(lambda n, o: out.append(n) if isinstance(o, h5py.Dataset) else None)
    except Exception:  # a damaged file: the list is only used in a message
        pass
    return out


def read_hdf5(path: Path, *, group: str | None = None,
              channel_map: ChannelMap | dict | None = None) -> Recording:
    """Read one recording group of the project's HDF5 layout (or a mapped foreign layout).

    Parameters
    ----------
    path : pathlib.Path
        The HDF5 file.
    group : str or None
        The group holding the recording; None: the root.
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
        The file cannot be opened as HDF5, the group is missing or is a dataset, or a
        channel is missing or malformed; the message names the file and, where one is at
        fault, the channel.
    """
    path = Path(path)
    cmap = resolve_channel_map(channel_map, path)
    try:
        fh = h5py.File(path, "r")
    except Exception as exc:  # OSError for non-HDF5 or truncated files
        raise library_error(exc, path=path, what="cannot open as HDF5",
                            hint="is the file complete and really HDF5?") from None
    with fh:
        where = group or "/"
        try:
            g = fh.get(where)
        except Exception as exc:  # damaged object headers
            raise library_error(exc, path=path, what=f"cannot open group '{where}'",
                                hint="is the file complete?") from None
        if g is None:
            raise InputError(f"no group '{where}' in the file", path=path,
                             hint="check the 'group' entry in the manifest")
        if not isinstance(g, h5py.Group):
            raise InputError(f"'{where}' is a dataset, not a group", path=path)
        native = _group_rate(g, path)
        return assemble_recording(cmap, lambda name: _dataset(g, name, path), path=path,
                                  source=source_name(path, group), native_rate=native,
                                  available=lambda: _names(g), notes=_notes(g))


def write_hdf5(path: Path, rec: Recording, *, group: str | None = None,
               write_time: bool = False, compression: str | None = None,
               attrs: dict | None = None, data_after_close: bool = False) -> Path:
    """Write a recording into a group of an HDF5 file (appending to the file).

    The channels ``rec`` has are written (absent optional channels are left out, and any
    left from an earlier write to the same group are removed). The sample rate goes into the
    ``sample_rate_hz`` attribute [Hz]; ``rec.notes`` into the ``torquemod_notes`` attribute.

    Parameters
    ----------
    path : pathlib.Path
        The file.
    rec : Recording
        The recording.
    group : str or None
        The group; None: the root.
    write_time : bool
        Also write the ``time_s`` dataset [s]. Default False.
    compression : str or None
        h5py compression filter, e.g. "gzip". Default None.
    attrs : dict or None
        Further attributes of the group. Default None.
    data_after_close : bool
        Without compression: the datasets' contiguous storage is allocated when they are
        created and the values are copied into it by plain positional writes after HDF5 has
        closed the file (the same float64 values and layout); those writes run without the GIL
        and outside h5py's lock, so that threads writing files overlap (the twin).
        Default False.

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    names = (["time_s"] if write_time else []) + [c for c in CHANNELS if c in rec.channels]
    if (data_after_close and compression is None and group is None and not attrs
            and not rec.notes and rec.n_samples > 0 and not os.path.exists(path)):
        _pwrite_all(path, _create_flat(path, rec, names))
        return path
    raw_writes = []
    with h5py.File(path, "a") as fh:
        g = fh.require_group(group) if group else fh
        g.attrs["torquemod_layout"] = LAYOUT_VERSION
        g.attrs["sample_rate_hz"] = float(rec.fs_hz)
        g.attrs["t0_s"] = float(rec.t0_s)
        if rec.notes:
            g.attrs[NOTES_ATTR] = np.array(list(rec.notes), dtype=h5py.string_dtype())
        elif NOTES_ATTR in g.attrs:
            del g.attrs[NOTES_ATTR]
        for k, v in (attrs or {}).items():
            g.attrs[k] = v
        for name in ["time_s", *CHANNELS]:
            if name in g and name not in names:
                del g[name]
        for name in names:
            data = rec.time_s() if name == "time_s" else rec.channels[name]
            if name in g:
                del g[name]
            if data_after_close and compression is None and len(data):
                arr = np.ascontiguousarray(data, dtype="<f8")
                dcpl = h5py.h5p.create(h5py.h5p.DATASET_CREATE)
                dcpl.set_alloc_time(h5py.h5d.ALLOC_TIME_EARLY)
                dcpl.set_fill_time(h5py.h5d.FILL_TIME_NEVER)
                ds = g.create_dataset(name, shape=arr.shape, dtype="<f8", dcpl=dcpl)
                raw_writes.append((ds.id.get_offset(), memoryview(arr).cast("B")))
            else:
                ds = g.create_dataset(name, data=np.asarray(data, dtype=np.float64),
                                      compression=compression)
            ds.attrs["unit"] = CHANNEL_UNITS[name]
    if raw_writes:
        _pwrite_all(path, raw_writes)
    return path


def _pwrite_all(path: Path, raw_writes: list[tuple[int, memoryview]]) -> None:
    """Copy each ``(offset, bytes)`` of ``raw_writes`` into ``path`` by positional writes
    (no GIL held while the kernel copies)."""
    fd = os.open(path, os.O_WRONLY)
    try:
        for offset, buf in raw_writes:
            while buf:  # pwrite may write less than asked
                done = os.pwrite(fd, buf, offset)
                offset, buf = offset + done, buf[done:]
    finally:
        os.close(fd)


@functools.cache
def _flat_plists() -> tuple:
    """The property lists, HDF5 types and scalar dataspace :func:`_create_flat` uses:
    those h5py's ``File(path, "a")``, ``attrs[name] = value`` and ``create_dataset`` use by
    default (libver earliest..latest, alignment 1, no object times, no attribute creation
    order), made once per process."""
    fapl = h5p.create(h5p.FILE_ACCESS)
    fapl.set_libver_bounds(h5f.LIBVER_EARLIEST, h5f.LIBVER_LATEST)
    fapl.set_alignment(1, 1)
    fcpl = h5p.create(h5p.FILE_CREATE)
    fcpl.set_obj_track_times(False)
    dcpl = h5p.create(h5p.DATASET_CREATE)
    dcpl.set_alloc_time(h5d.ALLOC_TIME_EARLY)
    dcpl.set_fill_time(h5d.FILL_TIME_NEVER)
    dcpl.set_obj_track_times(False)
    dcpl.set_attr_creation_order(0)
    text = h5py.string_dtype()
    types = {kind: (h5t.py_create(np.dtype(kind), logical=True), h5t.py_create(np.dtype(kind)))
             for kind in ("<f8", "<i8")}
    types["str"] = (h5t.py_create(text, logical=True), h5t.py_create(text))
    units = {name: np.asarray(unit, dtype=text) for name, unit in CHANNEL_UNITS.items()}
    return fapl, fcpl, dcpl, types, h5s.create_simple(()), units


def _create_flat(path: Path, rec: Recording, names: list[str]) -> list[tuple[int, memoryview]]:
    """Create the new file ``path`` holding ``rec`` at its root in the project's layout with
    h5py's low-level calls -- the same bytes as :func:`write_hdf5`'s h5py ``File`` path with
    ``data_after_close`` (tested byte for byte), in a third of its calls (h5py's high-level
    objects cost ~2.5 ms a file with the GIL held, this ~0.7 ms). The datasets' storage is
    allocated but not written; returns each dataset's ``(file offset, bytes)`` for
    :func:`_pwrite_all` after the file is closed."""
    fapl, fcpl, dcpl, types, scalar, units = _flat_plists()

    def attr(obj, name: bytes, value: np.ndarray, kind: str) -> None:
        file_type, mem_type = types[kind]
        h5a.create(obj, name, file_type, scalar).write(value, mem_type)

    raw_writes = []
    fid = h5f.create(os.fsencode(path), h5f.ACC_EXCL, fapl=fapl, fcpl=fcpl)
    try:
        root = h5g.open(fid, b"/")
        attr(root, b"torquemod_layout", np.asarray(LAYOUT_VERSION, dtype="<i8"), "<i8")
        attr(root, b"sample_rate_hz", np.asarray(float(rec.fs_hz)), "<f8")
        attr(root, b"t0_s", np.asarray(float(rec.t0_s)), "<f8")
        space = h5s.create_simple((rec.n_samples,))  # every dataset's
        for name in names:
            data = rec.time_s() if name == "time_s" else rec.channels[name]
            arr = np.ascontiguousarray(data, dtype="<f8")
            if arr.shape != (rec.n_samples,):
                raise InputError(f"{arr.size} samples where the recording has "
                                 f"{rec.n_samples}", path=path, channel=name,
                                 hint="give every channel the same length")
            ds = h5d.create(root, name.encode(), types["<f8"][0], space, dcpl=dcpl)
            attr(ds, b"unit", units[name], "str")
            raw_writes.append((ds.get_offset(), memoryview(arr).cast("B")))
            ds.close()
        root.close()
    finally:
        fid.close()
    return raw_writes
