"""The truth table of a simulated train run (``truth.parquet``, docs/format.md): reading it
beside a run, and the summaries that the twin's run report and the on-board report share.

The truth is a file format like the recordings: the measurement reads it to compare, and
never imports the twin that wrote it.
"""

from __future__ import annotations

import numpy as np


def load_truth(run):
    """The simulated truth named by ``[truth] file`` in a run's run.toml.

    Parameters
    ----------
    run : torquemod.io.run.Run
        The run.

    Returns
    -------
    pandas.DataFrame or None
        The truth table; None when absent or unreadable.
    """
    import pandas as pd
    t = run.extra.get("truth")
    if not isinstance(t, dict) or "file" not in t:
        return None
    path = run.folder / str(t["file"])
    try:
        return pd.read_parquet(path)
    except (OSError, ValueError):
        return None


def adhesion_utilisation(coa, available_adhesion):
    """The utilisation of the adhesion: CoA over the available adhesion; 1 at saturation.

    The one definition of the truth's utilisation: the truth table's ``utilisation`` column,
    ``simulate --train``'s "max utilisation" and the on-board report's truth line.

    Parameters
    ----------
    coa : float or array_like
        Utilised adhesion CoA [-].
    available_adhesion : float or array_like
        Available adhesion [-]: the maximum of the adhesion-creepage curve at the operating
        point.

    Returns
    -------
    float or ndarray
        CoA / available adhesion [-].

    Examples
    --------
    >>> float(adhesion_utilisation(0.1, 0.4))
    0.25
    """
    return np.asarray(coa, dtype=float) / np.asarray(available_adhesion, dtype=float)


def segment_summary(truth) -> list[dict]:
    """Per friction segment of the truth: its span, friction and peak adhesion (means).

    Parameters
    ----------
    truth : pandas.DataFrame
        The truth table.

    Returns
    -------
    list of dict
        One per segment, in track order: ``condition``, ``start_m`` and ``end_m`` [m],
        mean ``mu`` [-] and ``adhesion_peak`` [-], and ``max_utilisation`` [-]
        (:func:`adhesion_utilisation`).
    """
    out = []
    cond = truth["condition"].to_numpy()
    edges = np.flatnonzero(cond[1:] != cond[:-1]) + 1
    for lo, hi in zip(np.r_[0, edges], np.r_[edges, cond.size], strict=True):
        part = truth.iloc[lo:hi]
        out.append({"condition": str(cond[lo]), "start_m": float(part.position_m.iloc[0]),
                    "end_m": float(part.position_m.iloc[-1]), "mu": float(part.mu.mean()),
                    "adhesion_peak": float(part.adhesion_peak.mean()),
                    "max_utilisation": float(np.max(adhesion_utilisation(
                        part.coa, part.adhesion_peak)))})
    return out
