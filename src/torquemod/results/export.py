"""Result tables in further formats beside the ones a results folder always holds (the
rig's CSV, the train's Parquet): CSV, Parquet and MATLAB ``.mat`` (``--export csv,mat`` on
``torquemod process`` and ``onboard``; ``export=`` in the API).

A ``.mat`` file (MATLAB 5 format, :func:`scipy.io.savemat`) holds one struct named after the
table whose fields are its columns, each a column vector: ``load track.mat`` gives
``track.position_m``, ``track.mu``, ...; flags are 0/1 (uint8), text columns cell arrays of
char,
missing numbers NaN. Column names that are not MATLAB identifiers are made so (characters
other than letters, digits and ``_`` become ``_``; a leading digit gets ``x``).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from torquemod.errors import InputError

__all__ = ["EXPORT_FORMATS", "check_formats", "mat_name", "write_table"]

#: the formats :func:`write_table` writes, with their file suffixes
EXPORT_FORMATS = {"csv": ".csv", "mat": ".mat", "parquet": ".parquet"}


def check_formats(formats) -> tuple[str, ...]:
    """Export format names checked.

    Parameters
    ----------
    formats : str or sequence of str or None
        A comma-separated string or a sequence of names; None or empty: none.

    Returns
    -------
    tuple of str
        Known format names (:data:`EXPORT_FORMATS`), in order, without repeats.

    Raises
    ------
    InputError
        An unknown name, listing the known ones.

    Examples
    --------
    >>> check_formats("csv, csv")
    ('csv',)
    """
    if formats is None:
        return ()
    if isinstance(formats, str):
        formats = [f for f in formats.split(",")]
    out = []
    for f in formats:
        name = str(f).strip().lower().lstrip(".")
        if not name:
            continue
        if name not in EXPORT_FORMATS:
            raise InputError(f"unknown export format {f!r}",
                             hint=f"choose from {', '.join(EXPORT_FORMATS)}")
        if name not in out:
            out.append(name)
    return tuple(out)


def mat_name(name: str) -> str:
    """A name as a MATLAB identifier.

    Parameters
    ----------
    name : str
        The name.

    Returns
    -------
    str
        Letters, digits and ``_``; starting with a letter; at most 63 characters.

    Examples
    --------
    >>> mat_name("phase_deg (mean)")
    'phase_deg__mean_'
    """
    s = re.sub(r"\W", "_", str(name), flags=re.ASCII)
    if not s or not s[0].isalpha():
        s = "x" + s
    return s[:63]


def _mat_column(values) -> np.ndarray:
    a = np.asarray(values)
    if a.dtype == bool:
        return a.reshape(-1, 1)
    if a.dtype.kind in "iuf":
        return a.astype(np.float64).reshape(-1, 1)
    # text (or mixed): a cell array of char; missing values as empty text
    cells = np.empty((a.size, 1), dtype=object)
    for i, v in enumerate(a.ravel()):
        cells[i, 0] = "" if v is None or (isinstance(v, float) and np.isnan(v)) else str(v)
    return cells


def write_table(frame, base: Path, fmt: str, *, name: str | None = None) -> Path:
    """Write a table in an export format.

    Parameters
    ----------
    frame : pandas.DataFrame
        The table (SI units, as in the Parquet/CSV tables).
    base : pathlib.Path
        The file without suffix; the format's suffix is added.
    fmt : str
        One of :data:`EXPORT_FORMATS`.
    name : str or None
        The struct's name in a ``.mat`` file; None: the file's stem.

    Returns
    -------
    pathlib.Path
        The file written.

    Raises
    ------
    InputError
        Two columns become the same MATLAB name.
    """
    fmt = check_formats([fmt])[0]
    path = Path(str(base) + EXPORT_FORMATS[fmt])
    if fmt == "csv":
        frame.to_csv(path, index=False)
    elif fmt == "parquet":
        frame.to_parquet(path, index=False)
    else:
        from scipy.io import savemat
        struct = {}
        for col in frame.columns:
            key = mat_name(col)
            if key in struct:
                raise InputError(f"columns {col!r} and another both become {key!r} in MATLAB")
            struct[key] = _mat_column(frame[col].to_numpy())
        savemat(path, {mat_name(name or Path(base).name): struct}, do_compression=True,
                oned_as="column")
    return path
