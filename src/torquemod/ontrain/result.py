"""The result of one axle through the on-board estimator: the track, the run, the settings,
and what a notebook asks of it (a summary, a text report, the along-track table, plots,
saving and loading)."""

from __future__ import annotations

from dataclasses import dataclass, field
from html import escape
from typing import TYPE_CHECKING

from torquemod.io.run import Run
from torquemod.ontrain.estimator import TRACK_COLUMNS
from torquemod.ontrain.onboardconfig import OnboardConfig
from torquemod.ontrain.quality import QUALITY_OK

if TYPE_CHECKING:  # pandas is imported when first used
    import pandas as pd

__all__ = ["OnboardResult"]


@dataclass(frozen=True, repr=False, eq=False)
class OnboardResult:
    """One axle of a run through the on-board estimator.

    Attributes
    ----------
    run : Run
        The run manifest it came from.
    axle : int
        The axle (``[[recording]] axle``).
    track : pandas.DataFrame
        One row per window: :data:`~torquemod.ontrain.TRACK_COLUMNS` (``track.parquet``)
        and, straight from the estimator, a few diagnostics.
    config : OnboardConfig
        The estimator's settings.
    notes : tuple of str
        What the reader noted about the recording.
    seconds : float
        Wall time of the estimate [s].
    n_fits : int
        Fits of the creep-coefficient progression made.
    truth : pandas.DataFrame or None
        The simulated truth the run names (``[truth] file``), None for a real run.
    changes_m : tuple of float
        Positions [m] where the estimator detected a friction change (the along-track
        segments' limits).
    delay_s : float or None
        The further net delay of the torque behind the speed measured from the run and
        taken out [s] (None: read from the track's ``delay_s`` column).
    warnings : tuple of str
        What the user must know: stretches of track without the method's premise (no
        modulation, standstill, reverse running), a run too short for a friction estimate.
    segments : tuple of dict
        The available adhesion per segment between detected friction changes, each fitted
        once the segment had ended from all its steady windows: rows of
        :data:`~torquemod.ontrain.mufit.SEGMENT_COLUMNS` (``segments.csv``;
        :meth:`segment_table`).
    """

    run: Run
    axle: int
    track: pd.DataFrame
    config: OnboardConfig
    notes: tuple[str, ...] = ()
    seconds: float = 0.0
    n_fits: int = 0
    truth: pd.DataFrame | None = None
    changes_m: tuple[float, ...] = field(default=())
    delay_s: float | None = None
    warnings: tuple[str, ...] = ()
    segments: tuple[dict, ...] = ()

    def __post_init__(self):
        object.__setattr__(self, "segments", tuple(dict(s) for s in self.segments))
        object.__setattr__(self, "notes", tuple(self.notes))
        object.__setattr__(self, "warnings", tuple(self.warnings))
        object.__setattr__(self, "changes_m", tuple(float(c) for c in self.changes_m))

    # --- numbers ----------------------------------------------------------------------------
    @property
    def measured_delay_s(self) -> float:
        """The further torque-behind-speed delay taken out [s] (0 while the run did not
        determine one)."""
        if self.delay_s is not None:
            return float(self.delay_s)
        t = self.track
        return float(t["delay_s"].iloc[-1]) if "delay_s" in t and len(t) else 0.0

    def summary(self) -> dict:
        """The axle in numbers: windows, length [m], shares of windows with μ, flagged low
        adhesion and slip, ``mu_median`` and ``mu_lower_bound`` (one summary of the same
        windows, the bound never above μ:
        :func:`~torquemod.ontrain.alongtrack.run_mu_summary`; per stretch:
        :meth:`along_track`), the friction changes [m], the fits and the wall time [s]."""
        from torquemod.ontrain.alongtrack import run_mu_summary
        t = self.track
        mu, bound = run_mu_summary(t)
        ok = (t["quality"] == QUALITY_OK) if "quality" in t else t["mu"].notna() | True
        out = {"axle": self.axle, "windows": len(t),
               "mu_given_share": float(t["mu"].notna().mean()) if len(t) else 0.0,
               "measurable_share": float(ok.mean()) if len(t) else 0.0,
               "low_adhesion_share": float(t["low_adhesion"].mean()) if len(t) else 0.0,
               "slip_share": float(t["slip"].mean()) if len(t) else 0.0,
               "mu_fits": self.n_fits, "seconds": self.seconds,
               "length_m": float(t["position_m"].iloc[-1] - t["position_m"].iloc[0])
               if len(t) else 0.0,
               "changes_m": list(self.changes_m),
               "measured_delay_s": self.measured_delay_s,
               "segments": [dict(s) for s in self.segments]}
        if mu is not None:
            out["mu_median"] = mu
        if bound is not None:
            out["mu_lower_bound"] = bound
        return out

    def to_frame(self):
        """The ``track.parquet`` table (a copy): exactly
        :data:`~torquemod.ontrain.TRACK_COLUMNS`, flags as bool, ``quality`` as text."""
        t = self.track[list(TRACK_COLUMNS)].copy()
        t["low_adhesion"] = t["low_adhesion"].astype(bool)
        t["slip"] = t["slip"].astype(bool)
        if "quality" in t:
            t["quality"] = t["quality"].astype(str)
        return t

    def along_track(self, by: str = "segment", *, length_m: float = 1000.0):
        """The along-track table (:func:`torquemod.ontrain.alongtrack.along_track`): one row
        per segment between detected friction changes (``by="segment"``) or per
        ``length_m`` [m] (``by="km"``)."""
        from torquemod.ontrain.alongtrack import along_track
        return along_track(self.track, changes_m=self.changes_m, by=by, length_m=length_m)

    def segment_table(self):
        """The per-segment table (``segments.csv``): one row per segment between detected
        friction changes, :data:`~torquemod.ontrain.mufit.SEGMENT_COLUMNS` (the available
        adhesion where determined, the best fit, its 95 % interval, the lower bound)."""
        import pandas as pd

        from torquemod.ontrain.mufit import SEGMENT_COLUMNS
        t = pd.DataFrame([dict(s) for s in self.segments], columns=list(SEGMENT_COLUMNS))
        for c in SEGMENT_COLUMNS:
            if c not in ("segment", "windows", "determined", "best_law"):
                t[c] = pd.to_numeric(t[c], errors="coerce").astype(float)
        t["determined"] = t["determined"].astype(bool)
        return t

    # --- text ------------------------------------------------------------------------------
    def __repr__(self) -> str:
        s = self.summary()
        return (f"<OnboardResult {self.run.manifest_path.name} axle {self.axle}: "
                f"{s['windows']} windows over {s['length_m']:.0f} m, mu determined in "
                f"{100 * s['mu_given_share']:.0f} %, {len(self.changes_m)} friction changes, "
                f"low adhesion {100 * s['low_adhesion_share']:.1f} %>")

    def report(self) -> str:
        """A text report: the run, the summary and the along-track table per segment."""
        from torquemod.ontrain.report import headline
        seg = self.along_track()
        cols = ["start_m", "end_m", "windows", "condition", "mu", "mu_low_95", "mu_high_95",
                "mu_lower_bound", "low_adhesion_share", "coa_reached", "probe_depth"]
        seg = seg[cols].assign(start_m=seg["start_m"].round().astype(int),
                               end_m=seg["end_m"].round().astype(int))
        import pandas as pd
        with pd.option_context("display.width", 250, "display.max_columns", 50):
            table = seg.to_string(index=False, float_format=lambda v: f"{v:.3f}", na_rep="-")
        segs = self.segment_table()
        with pd.option_context("display.width", 250, "display.max_columns", 50):
            fits = segs.to_string(index=False, float_format=lambda v: f"{v:.3f}", na_rep="-")
        return "\n".join([*headline(self), "", "Along the track, per segment between "
                          "detected friction changes:", table, "",
                          "The available adhesion per segment, fitted from all its windows "
                          "once it ended (adhesion_available where determined; best fit and "
                          "95 % interval always):", fits])

    def _repr_html_(self) -> str:
        from torquemod.ontrain.report import along_track_html
        return f"<p>{escape(repr(self))}</p>" + along_track_html(self.along_track())

    # --- figures ----------------------------------------------------------------------------
    def plot_mu(self, *, ax=None):
        """μ along the track (where determined, with its 95 % interval), the lower bound per
        segment and the CoA; the truth when simulated. On ``ax`` (a new Figure, not pyplot,
        when None); returns the Axes."""
        from torquemod.ontrain.report import plot_mu
        return plot_mu(self, ax=ax)

    def plot_phase(self, *, ax=None):
        """The phase lag of the speed behind the torque per window (+-2 standard errors),
        scaled to the body of the data. Returns the Axes."""
        from torquemod.ontrain.report import plot_phase
        return plot_phase(self, ax=ax)

    def plot_utilisation(self, *, ax=None):
        """The utilisation of the adhesion along the track and the flags. Returns the
        Axes."""
        from torquemod.ontrain.report import plot_utilisation
        return plot_utilisation(self, ax=ax)

    # --- files ------------------------------------------------------------------------------
    def save(self, folder, *, force: bool = False, export=()):
        """Write the results folder ``folder`` (what ``torquemod onboard`` writes for this
        axle) atomically; ``export``: extra table formats ("csv", "mat"). Returns its
        path; :func:`torquemod.load_onboard` reads it back."""
        from torquemod.ontrain.folder import save_onboard
        return save_onboard([self], folder, force=force, export=export)

