"""MATLAB ``.mat`` recordings: v4/v5/v7 through ``scipy.io.loadmat``, v7.3 (HDF5) through
``h5py``.

Each channel is a numeric vector variable, by default named as in the CSV format
(``time_s``, ``torque_nm``, ...), or as mapped in the manifest's ``[channels]`` table. A name
may reach into a struct with dots (``"daq.Torque"``); the recording's ``group`` names a struct
that holds all channels. Without a time vector the sample rate comes from a scalar variable
``sample_rate_hz`` or ``fs`` [Hz] (with optional ``t0_s`` [s]) next to the channels. A .mat
file has no units: give them in ``[channels]`` when they are not the method's.
"""

from __future__ import annotations

import io
import math
import struct
import zlib
from pathlib import Path

import h5py
import numpy as np
import scipy.io

from torquemod.errors import InputError
from torquemod.io.channels import (
    ChannelMap,
    RawChannel,
    library_error,
    resolve_channel_map,
    source_name,
)
from torquemod.io.experiment import Recording
from torquemod.io.timebase import assemble_recording

#: Scalar variables giving the sample rate [Hz] when there is no time vector.
RATE_NAMES = ("sample_rate_hz", "fs")
_NUMERIC_CLASSES = {"double", "single", "logical", "int8", "uint8", "int16", "uint16",
                    "int32", "uint32", "int64", "uint64"}
_HINT = "is the file complete and really a MATLAB .mat file?"


def _parts(name: str) -> list[str]:
    return [p for p in name.replace("/", ".").split(".") if p]


def _scalar(value: object) -> float | None:
    arr = np.asarray(value)
    if arr.size != 1 or arr.dtype.kind not in "iuf":
        return None
    out = float(arr.reshape(-1)[0])
    return out if np.isfinite(out) else None


def _native_rate(get, path: Path) -> tuple[float, float] | None:
    for name in RATE_NAMES:
        value = get(name)
        if value is None:
            continue
        fs = _scalar(value)
        if fs is None or fs <= 0:
            raise InputError(f"variable '{name}' must be a positive scalar sample rate [Hz]",
                             path=path)
        t0_value = get("t0_s")
        t0 = _scalar(t0_value) if t0_value is not None else 0.0
        return fs, t0 if t0 is not None else 0.0
    return None


# --- v5 structure check -------------------------------------------------------------------
# scipy's compiled MAT v5 reader trusts the element tags: a damaged tag (an unknown data type,
# a size past the end) can crash the interpreter instead of raising. The checks below walk the
# tags first, in pure Python, and turn such damage into an InputError.

_MI_ITEMSIZE = {1: 1, 2: 1, 3: 2, 4: 2, 5: 4, 6: 4, 7: 4, 9: 8, 12: 8, 13: 8, 16: 1, 17: 2,
                18: 4}
_MI_MATRIX, _MI_COMPRESSED = 14, 15
_NUMERIC_MX = set(range(4, 16)) - {5}  # char and numeric classes (5 is sparse)
_OPAQUE_MX = (16, 17)  # function handles and MATLAB objects
_MI_UTF = (16, 17, 18)
_MAX_DEPTH = 32


class _Damaged(Exception):
    """Internal: the MAT v5 element structure is inconsistent (message says where)."""


def _tags(buf: bytes, start: int, end: int, endian: str):
    """Yield ``(mdtype, payload_start, nbytes)`` of the elements in ``buf[start:end]``."""
    pos = start
    while pos < end:
        if end - pos < 8:
            raise _Damaged(f"element tag cut off at byte {pos}")
        mdtype, nbytes = struct.unpack_from(endian + "II", buf, pos)
        if mdtype >> 16:  # small data element: size and type in 4 bytes, data in the next 4
            nbytes, mdtype = mdtype >> 16, mdtype & 0xFFFF
            if nbytes > 4:
                raise _Damaged(f"small element of {nbytes} bytes at byte {pos}")
            yield mdtype, pos + 4, nbytes
            pos += 8
            continue
        if mdtype not in _MI_ITEMSIZE and mdtype not in (_MI_MATRIX, _MI_COMPRESSED):
            raise _Damaged(f"unknown data type {mdtype} at byte {pos}")
        stop = pos + 8 + nbytes
        if stop > end:
            raise _Damaged(f"element at byte {pos} runs past its end")
        yield mdtype, pos + 8, nbytes
        pos = stop if mdtype == _MI_COMPRESSED else stop + (-nbytes % 8)


def _check_matrix(buf: bytes, start: int, nbytes: int, endian: str, depth: int) -> None:
    """Check one miMATRIX element: flags, dimensions, name, then what its class needs."""
    if depth > _MAX_DEPTH:
        raise _Damaged("structs nested too deep")
    if nbytes == 0:  # an empty matrix
        return
    parts = list(_tags(buf, start, start + nbytes, endian))
    if len(parts) < 2 or parts[0][0] != 6 or parts[0][2] != 8:
        raise _Damaged(f"matrix at byte {start} lacks its array flags")
    flags = struct.unpack_from(endian + "I", buf, parts[0][1])[0]
    mx_class, complex_ = flags & 0xFF, bool(flags & 0x0800)
    nested = [(pos, size) for mdtype, pos, size in parts if mdtype == _MI_MATRIX]
    if mx_class in _OPAQUE_MX:  # MATLAB objects (string, datetime, ...): own layout
        for pos, size in nested:
            _check_matrix(buf, pos, size, endian, depth + 1)
        return
    if not 1 <= mx_class <= 15:
        raise _Damaged(f"unknown array class {mx_class} at byte {start}")
    if len(parts) < 3 or parts[1][0] != 5 or parts[1][2] < 8:
        raise _Damaged(f"matrix at byte {start} lacks its dimensions or name")
    n_dims = parts[1][2] // 4
    dims = struct.unpack_from(endian + f"{n_dims}i", buf, parts[1][1])
    if min(dims) < 0:
        raise _Damaged(f"bad dimensions {dims} at byte {start}")
    count = math.prod(dims)
    if mx_class in _NUMERIC_MX:
        if len(parts) != 4 + complex_:
            raise _Damaged(f"matrix at byte {start} has {len(parts) - 3} data parts, "
                           f"expected {1 + complex_}")
        for mdtype, _, size in parts[3:]:
            if mdtype not in _MI_ITEMSIZE or (
                    mdtype not in _MI_UTF and size != count * _MI_ITEMSIZE[mdtype]):
                raise _Damaged(f"data of the matrix at byte {start} do not fit its "
                               f"dimensions {dims}")
    elif mx_class == 5 and len(parts) != 6 + complex_:  # sparse: ir, jc, pr[, pi]
        raise _Damaged(f"sparse matrix at byte {start} is incomplete")
    elif mx_class == 1 and len(parts) != 3 + count:  # cell
        raise _Damaged(f"cell array at byte {start} holds {len(parts) - 3} of {count} cells")
    elif mx_class in (2, 3):  # struct, object: [class name,] field name length, names
        head = 4 if mx_class == 2 else 5
        if len(parts) < head + 1 or parts[head - 1][2] != 4:
            raise _Damaged(f"struct at byte {start} lacks its field names")
        name_len = struct.unpack_from(endian + "i", buf, parts[head - 1][1])[0]
        names_size = parts[head][2]
        n_fields = names_size // name_len if name_len > 0 else 0
        if name_len <= 0 or names_size % name_len or len(parts) != head + 1 + n_fields * count:
            raise _Damaged(f"struct at byte {start} does not match its field names")
    for pos, size in nested:
        _check_matrix(buf, pos, size, endian, depth + 1)


def check_mat5_structure(buf: bytes) -> None:
    """Check the element tags of a MAT v5 file.

    Parameters
    ----------
    buf : bytes
        The file's content.

    Raises
    ------
    _Damaged
        The header is short, a top-level element has an unexpected type, or a compressed
        variable does not inflate to a matrix (the reader turns it into an InputError naming
        the file).
    """
    if len(buf) < 128:
        raise _Damaged("shorter than the 128-byte MAT header")
    endian = {b"IM": "<", b"MI": ">"}.get(buf[126:128])
    if endian is None:
        return  # not v5 (v4 has no header); scipy's pure-Python v4 reader handles it
    for mdtype, pos, nbytes in _tags(buf, 128, len(buf), endian):
        if mdtype == _MI_COMPRESSED:
            try:
                inner = zlib.decompress(buf[pos:pos + nbytes])
            except zlib.error as exc:
                raise _Damaged(f"compressed variable at byte {pos}: {exc}") from None
            for sub_type, sub_pos, sub_n in _tags(inner, 0, len(inner), endian):
                if sub_type != _MI_MATRIX:
                    raise _Damaged(f"compressed variable at byte {pos} is not a matrix")
                _check_matrix(inner, sub_pos, sub_n, endian, 0)
        elif mdtype == _MI_MATRIX:
            _check_matrix(buf, pos, nbytes, endian, 0)
        else:
            raise _Damaged(f"top-level element of type {mdtype} at byte {pos}")


# --- v4 to v7: scipy.io -------------------------------------------------------------------

def _walk_dict(root: dict, name: str) -> object | None:
    node: object = root
    for part in _parts(name):
        if not isinstance(node, dict) or part not in node:
            return None
        node = node[part]
    return node


def _dict_names(root: dict, prefix: str = "") -> list[str]:
    out: list[str] = []
    for key, value in root.items():
        if key.startswith("__"):
            continue
        if isinstance(value, dict):
            out += _dict_names(value, f"{prefix}{key}.")
        else:
            out.append(f"{prefix}{key}")
    return out


def _read_v5(path: Path, group: str | None, cmap: ChannelMap) -> Recording:
    try:
        buf = path.read_bytes()
    except OSError as exc:
        raise InputError(f"cannot open ({exc.strerror})", path=path) from None
    try:
        check_mat5_structure(buf)
    except (_Damaged, struct.error) as exc:
        raise InputError(f"damaged MATLAB file ({exc})", path=path, hint=_HINT) from None
    try:
        doc = scipy.io.loadmat(io.BytesIO(buf), simplify_cells=True)
    except Exception as exc:  # scipy raises ValueError/TypeError/zlib.error/... on bad files
        raise library_error(exc, path=path, what="cannot read as a MATLAB file",
                            hint=_HINT) from None
    root = doc
    if group is not None:
        root = _walk_dict(doc, group)
        if not isinstance(root, dict):
            raise InputError(f"no struct '{group}' in the file", path=path,
                             hint="check the 'group' entry in the manifest")

    def get(name: str) -> object | None:
        return _walk_dict(root, name)

    def lookup(name: str) -> RawChannel | None:
        value = get(name)
        if value is None:
            return None
        if isinstance(value, dict):
            raise InputError(f"'{name}' is a struct, not a numeric vector", path=path,
                             hint="map one of its fields, e.g. \"struct.field\"")
        return RawChannel(np.asarray(value))

    return assemble_recording(cmap, lookup, path=path, source=source_name(path, group),
                              native_rate=_native_rate(get, path),
                              available=lambda: _dict_names(root))


# --- v7.3: HDF5 ---------------------------------------------------------------------------

def _matlab_class(obj: h5py.HLObject) -> str | None:
    value = obj.attrs.get("MATLAB_class")
    if isinstance(value, bytes):
        return value.decode("ascii", errors="replace")
    return value if isinstance(value, str) else None


def _read_dataset(node: h5py.Group, name: str, path: Path, *, vector: bool = False
                  ) -> np.ndarray | None:
    """The variable ``name`` below ``node``, None if absent; ``vector``: a matrix is refused
    before its values are read."""
    try:
        obj = node.get("/".join(_parts(name)) or ".")
        if obj is None:
            return None
        if not isinstance(obj, h5py.Dataset):
            raise InputError(f"'{name}' is a struct, not a numeric vector", path=path,
                             hint="map one of its fields, e.g. \"struct.field\"")
        cls = _matlab_class(obj)
        if cls is not None and cls not in _NUMERIC_CLASSES:
            raise InputError(f"'{name}' is a MATLAB {cls}, not a numeric vector", path=path,
                             hint="map a numeric variable")
        if obj.attrs.get("MATLAB_empty"):
            return np.zeros(0)
        if vector and sum(d > 1 for d in obj.shape) > 1:
            raise InputError(f"'{name}': expected a 1-D signal, got shape {obj.shape}",
                             path=path, hint="map a vector (one value per sample)")
        return np.asarray(obj[()])
    except InputError:
        raise
    except Exception as exc:  # h5py on damaged object headers or data
        raise library_error(exc, path=path, what=f"cannot read variable '{name}'",
                            hint=_HINT) from None


def _h5_names(node: h5py.Group) -> list[str]:
    out: list[str] = []
    try:
        node.visititems(lambda n, o: out.append(n.replace("/", "."))
                        if isinstance(o, h5py.Dataset) and not n.startswith("#") else None)
    except Exception:  # a damaged file: the list is only used in a message
        pass
    return out


def _read_v73(path: Path, group: str | None, cmap: ChannelMap) -> Recording:
    try:
        fh = h5py.File(path, "r")
    except Exception as exc:  # OSError on truncated files
        raise library_error(exc, path=path, what="cannot open as a MATLAB v7.3 file",
                            hint=_HINT) from None
    with fh:
        root: h5py.Group = fh
        if group is not None:
            try:
                node = fh.get("/".join(_parts(group)) or "/")
            except Exception as exc:  # damaged object headers
                raise library_error(exc, path=path, what=f"cannot open struct '{group}'",
                                    hint=_HINT) from None
            if not isinstance(node, h5py.Group):
                raise InputError(f"no struct '{group}' in the file", path=path,
                                 hint="check the 'group' entry in the manifest")
            root = node

        def lookup(name: str) -> RawChannel | None:
            values = _read_dataset(root, name, path, vector=True)
            return None if values is None else RawChannel(values)

        native = _native_rate(lambda n: _read_dataset(root, n, path), path)
        return assemble_recording(cmap, lookup, path=path, source=source_name(path, group),
                                  native_rate=native, available=lambda: _h5_names(root))


def is_mat73(path: Path) -> bool:
    """Whether a file is a MATLAB v7.3 file (HDF5 with a 512-byte MATLAB header).

    Parameters
    ----------
    path : pathlib.Path
        The file.

    Returns
    -------
    bool
        True for v7.3.
    """
    try:
        return bool(h5py.is_hdf5(path))
    except Exception:  # unreadable: let the v5 reader report it
        return False


def read_mat(path: Path, *, group: str | None = None,
             channel_map: ChannelMap | dict | None = None) -> Recording:
    """Read a MATLAB .mat recording of any version (v5 and v7.3 included).

    Parameters
    ----------
    path : pathlib.Path
        The MATLAB file.
    group : str or None
        A struct variable holding the channels; None: top-level variables.
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
        The file is damaged or not a MAT file, the struct or a channel is missing, or a
        channel is not a numeric vector; the message names the file and, where one is at
        fault, the channel.
    """
    path = Path(path)
    cmap = resolve_channel_map(channel_map, path)
    if is_mat73(path):
        return _read_v73(path, group, cmap)
    return _read_v5(path, group, cmap)


def write_mat(path: Path, rec: Recording) -> Path:
    """Write a MATLAB (v5) recording.

    One column vector per channel ``rec`` has, named as in the CSV format (SI units), and the
    scalars ``sample_rate_hz`` [Hz] and ``t0_s`` [s], so it reads back exactly without a
    ``[channels]`` table.

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
    from torquemod.io.experiment import CHANNELS
    doc = {name: np.asarray(rec.channels[name], dtype=np.float64).reshape(-1, 1)
           for name in CHANNELS if name in rec.channels}
    doc["sample_rate_hz"] = float(rec.fs_hz)
    doc["t0_s"] = float(rec.t0_s)
    try:
        scipy.io.savemat(path, doc, do_compression=True)
    except OSError as exc:
        raise InputError(f"cannot write ({exc})", path=path) from None
    return path
