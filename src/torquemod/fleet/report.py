"""The fleet's report: ``OUT/fleet_report.html`` of :func:`torquemod.fleet.run.run_fleet`.

One self-contained page (inline CSS, figures as base64 PNG, every text escaped; the style of
:mod:`torquemod.report.html`): the runs (status, kind, vehicle, date, recorded duration, rows,
key results), the failures with their one-line messages, the rig experiments' steps (phase
and CoA per DC torque step) and two figures: phase against CoA of every rig step, and the
lower bound of mu (with mu where determined) along the track of every train run. Written with
the fleet's summary by the results writer, so the page is never seen half-written.
"""

from __future__ import annotations

import base64
import datetime as _dt
import io
from html import escape
from pathlib import Path

import numpy as np
import pandas as pd

from torquemod._util.fsutil import write_atomic
from torquemod._version import __version__
from torquemod.report.html import CSS, table

_RUN_HEADERS = ["run", "kind", "status", "vehicle", "date", "recorded [s]", "rows", "mu",
                "mu lower bound", "mu given", "low adhesion", "slip", "task [s]"]


def _partition(out: Path, table_name: str, row) -> Path:
    return out / table_name / f"vehicle={row.vehicle}" / f"date={row.date}" / f"run={row.run}"


def load_steps(out: Path, summary: pd.DataFrame) -> pd.DataFrame:
    """The steps of the summary's good rig runs.

    Parameters
    ----------
    out : pathlib.Path
        The fleet's output folder.
    summary : pandas.DataFrame
        The fleet summary.

    Returns
    -------
    pandas.DataFrame
        steps rows with a ``run`` column; empty if none.
    """
    parts = []
    for row in summary.itertuples():
        if row.kind == "rig" and row.status != "failed":
            path = _partition(out, "steps", row) / "part-0.parquet"
            if path.is_file():
                parts.append(pd.read_parquet(path).assign(run=row.run))
    return pd.concat(parts, ignore_index=True) if parts else pd.DataFrame()


def load_tracks(out: Path, summary: pd.DataFrame) -> pd.DataFrame:
    """The track rows of the summary's good train runs.

    Parameters
    ----------
    out : pathlib.Path
        The fleet's output folder.
    summary : pandas.DataFrame
        The fleet summary.

    Returns
    -------
    pandas.DataFrame
        track rows with ``run`` and ``axle`` columns; empty if none.
    """
    parts = []
    for row in summary.itertuples():
        if row.kind == "train" and row.status != "failed":
            for path in sorted(_partition(out, "track", row).glob("axle=*/part-0.parquet")):
                axle = int(path.parent.name.split("=", 1)[1])
                parts.append(pd.read_parquet(path).assign(run=row.run, axle=axle))
    return pd.concat(parts, ignore_index=True) if parts else pd.DataFrame()


def _png(fig) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100)
    return buf.getvalue()


def _figure(png: bytes, caption: str) -> str:
    data = base64.b64encode(png).decode("ascii")
    return (f'<figure><img alt="{escape(caption)}" src="data:image/png;base64,{data}">'
            f"<figcaption>{escape(caption)}</figcaption></figure>")


def phase_coa_figure(steps: pd.DataFrame) -> bytes:
    """Phase against CoA of every rig step, one marker series per run.

    Parameters
    ----------
    steps : pandas.DataFrame
        The steps (:func:`load_steps`).

    Returns
    -------
    bytes
        PNG of phase [deg] against CoA [-].
    """
    from matplotlib.figure import Figure
    fig = Figure(figsize=(7, 4.2), layout="constrained")
    ax = fig.add_subplot()
    for run, g in steps.groupby("run", sort=True):
        ax.plot(g["coa"], g["phase_deg"], "o-", ms=4, lw=0.8, label=str(run))
    ax.set_xlabel("CoA [-]")
    ax.set_ylabel("phase [deg]")
    ax.grid(alpha=0.3)
    if steps["run"].nunique() <= 12:
        ax.legend(fontsize=7)
    return _png(fig)


#: the stretch [m] of the fleet figure's lower-bound steps
_STRETCH_M = 250.0


def mu_track_figure(tracks: pd.DataFrame) -> bytes:
    """The lower bound of mu per stretch and mu where determined, against position.

    Per :data:`_STRETCH_M` of track (steps; left out where the stretch holds different
    rails: :func:`torquemod.ontrain.alongtrack.along_track`), per run and axle.

    Parameters
    ----------
    tracks : pandas.DataFrame
        The track rows (:func:`load_tracks`).

    Returns
    -------
    bytes
        PNG of mu [-] against position [m].
    """
    from matplotlib.figure import Figure

    from torquemod.ontrain.alongtrack import along_track
    fig = Figure(figsize=(7, 4.2), layout="constrained")
    ax = fig.add_subplot()
    for (run, axle), g in tracks.groupby(["run", "axle"], sort=True, observed=True):
        label = f"{run} axle {axle}"
        part = along_track(g, by="km", length_m=_STRETCH_M)
        bound = part["mu_lower_bound"].where(part["condition"] != "mixed").to_numpy(float)
        xs = np.column_stack([part["start_m"], part["end_m"],
                              np.full(len(part), np.nan)]).ravel()
        (line,) = ax.plot(xs, np.repeat(bound, 3), lw=1.6,
                          label=f"{label}: lower bound per {_STRETCH_M:.0f} m")
        given = g["mu"].notna()
        if given.any():
            ax.plot(g.loc[given, "position_m"], g.loc[given, "mu"], ".", ms=3,
                    color=line.get_color(), label=f"{label}: mu")
    ax.set_ylim(bottom=0)
    ax.set_xlabel("position [m]")
    ax.set_ylabel("mu [-]")
    ax.grid(alpha=0.3)
    if tracks["run"].nunique() <= 8:
        ax.legend(fontsize=7)
    return _png(fig)


def _value(v):
    """None for a missing value (None, NaN, pd.NA), else ``v``."""
    return None if v is None or (pd.api.types.is_scalar(v) and pd.isna(v)) else v


def render_fleet_report(summary: pd.DataFrame, failures: pd.DataFrame,
                        steps: pd.DataFrame, tracks: pd.DataFrame) -> str:
    """The fleet report page as a string (a pure function of the tables).

    Parameters
    ----------
    summary : pandas.DataFrame
        One row per run.
    failures : pandas.DataFrame
        The failed rows.
    steps : pandas.DataFrame
        The good rig runs' steps.
    tracks : pandas.DataFrame
        The good train runs' track rows.

    Returns
    -------
    str
        The HTML page.
    """
    counts = summary["status"].value_counts().to_dict()
    head = (f"{len(summary)} runs: {counts.get('processed', 0)} processed, "
            f"{counts.get('skipped', 0)} unchanged (skipped), {counts.get('failed', 0)} "
            f"failed; {(summary['kind'] == 'rig').sum()} rig experiments, "
            f"{(summary['kind'] == 'train').sum()} train runs")
    rows = []
    for r in summary.itertuples():
        share = _value(r.mu_given_share)
        rows.append([r.run, r.kind, r.status, str(_value(r.vehicle) or "—"),
                     str(_value(r.date) or "—"), _value(r.duration_s), _value(r.n_rows),
                     _value(r.mu), _value(r.mu_lower_bound),
                     None if share is None else f"{100 * share:.0f} %",
                     _value(r.low_adhesion_windows), _value(r.slip_windows),
                     _value(r.seconds)])
    parts = [f"<h1>Fleet report</h1><p>{escape(head)}. torquemod {escape(__version__)}, "
             f"{escape(_dt.datetime.now(_dt.UTC).isoformat(timespec='seconds'))}.</p>",
             "<h2>Runs</h2>", table(_RUN_HEADERS, rows, left=5),
             "<p>mu: rig, the creep-curve fit (Polach, else mu from the phase) where the steps "
             "determine it; train, the median of the windows where mu is determined. mu lower "
             "bound: rig, the fit's bound; train, the median of the windows' 95 % lower "
             "bound. mu given: share of windows with mu. low adhesion, slip: windows "
             "flagged.</p>", "<h2>Failures</h2>"]
    if failures.empty:
        parts.append("<p>none</p>")
    else:
        parts.append(table(["run", "kind", "message"],
                           [[f.run, f.kind, f.message] for f in failures.itertuples()],
                           left=3))
    if not steps.empty:
        parts.append("<h2>Rig experiments: steps</h2>")
        parts.append(table(["run", "step", "DC torque [N*m]", "phase [deg]", "phase std",
                            "CoA", "cycles", "slip"],
                           [[s.run, int(s.step), s.dc_torque_nm, s.phase_deg,
                             s.phase_std_deg, s.coa, int(s.n_cycles), bool(s.slip)]
                            for s in steps.itertuples()], left=1))
        parts.append(_figure(phase_coa_figure(steps), "Phase against CoA, every step of "
                                                      "every rig experiment"))
    if not tracks.empty:
        parts.append("<h2>Train runs: mu along the track</h2>")
        parts.append(_figure(mu_track_figure(tracks), f"Lower bound of mu per {_STRETCH_M:.0f} m "
                             "(steps; none where a stretch holds different rails) and mu where "
                             "the data determine it (dots)"))
    return ("<!DOCTYPE html><html lang=\"en\"><head><meta charset=\"utf-8\">"
            f"<title>torquemod fleet</title><style>{CSS}</style></head><body>"
            + "\n".join(parts) + "</body></html>")


def write_fleet_report(out: str | Path, summary: pd.DataFrame, failures: pd.DataFrame,
                       dest: str | Path | None = None) -> Path:
    """Write ``fleet_report.html`` (temporary file and rename).

    Parameters
    ----------
    out : str or pathlib.Path
        The fleet's output folder (its partitions are read).
    summary : pandas.DataFrame
        One row per run.
    failures : pandas.DataFrame
        The failed rows.
    dest : str or pathlib.Path or None
        The folder to write the page into. Default None: ``out`` (the results writer
        passes its staging folder).

    Returns
    -------
    pathlib.Path
        The report.
    """
    out = Path(out)
    page = render_fleet_report(summary, failures, load_steps(out, summary),
                               load_tracks(out, summary))
    return write_atomic(Path(dest or out) / "fleet_report.html", lambda fh: fh.write(page))
