"""The typed result of the fit stage (:func:`torquemod.analyze`), lmfit-style: the fits, the
theory check, the onset, the extended steps table, a text ``report()``, plots that take an
``ax`` and ``to_dict()`` giving the ``fit.json`` document.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from html import escape
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from torquemod._util.jsonutil import to_jsonable
from torquemod._version import __version__
from torquemod.analysis.creep import CreepPoints, OnsetResult, TheoryCheck
from torquemod.analysis.options import FitOptions

if TYPE_CHECKING:  # named for the types only
    from torquemod.analysis.phasefitresult import PhaseMuFit
    from torquemod.analysis.polachfitresult import PolachFit

__all__ = ["Analysis", "curve_check", "from_saved", "phase_keys", "saved_state"]


def phase_keys(pfit) -> dict:
    """The fit.json keys of the fit from the phase.

    ``mu_from_phase*`` (kept from earlier versions): the available adhesion (the maximum of
    the adhesion-creepage curve), a lower bound as the interval's low end when it is not
    determined. ``adhesion_available_from_phase*`` name the same quantity explicitly, with
    the interval when it is closed, the lower bound, the probe depth (utilisation) that would
    determine it, and ``mu0_from_phase``, the law's friction coefficient, where the data
    identify it. ``mu_from_phase_constant_source`` says where the rigid-wheel constant C
    came from: ``"rig inertia"``, ``"amplitudes"`` (measured from the torque and wheel-speed
    amplitudes, no inertia given), ``"given"`` or ``"not given"`` (absent when there is no
    fit from the phase).

    Parameters
    ----------
    pfit : PhaseMuFit or None
        The fit; None gives every key empty.

    Returns
    -------
    dict
        JSON-ready keys; adhesions and friction coefficients [-], probe depth [-].
    """
    keys = ("adhesion_available_from_phase", "adhesion_available_from_phase_low",
            "adhesion_available_from_phase_high", "adhesion_available_from_phase_lower_bound",
            "mu0_from_phase", "mu0_from_phase_low", "mu0_from_phase_high",
            "probe_depth_needed_from_phase", "phase_fit_best_law")
    if pfit is None:
        return {"mu_from_phase": None, "mu_from_phase_stderr": None,
                "mu_from_phase_interval_95": [None, None], "mu_from_phase_determined": False,
                **dict.fromkeys(keys), "adhesion_available_from_phase_determined": False}
    lo, hi = pfit.mu_interval_95
    a = pfit.adhesion.to_dict()
    return {"mu_from_phase": pfit.mu if pfit.mu_determined else None,
            "mu_from_phase_stderr": pfit.mu_stderr if pfit.mu_determined else None,
            "mu_from_phase_interval_95": [lo, hi if pfit.mu_determined else None],
            "mu_from_phase_determined": bool(pfit.mu_determined),
            "mu_from_phase_estimand": a["estimand"],
            "adhesion_available_from_phase": a["adhesion_available"],
            "adhesion_available_from_phase_low": a["adhesion_available_low"],
            "adhesion_available_from_phase_high": a["adhesion_available_high"],
            "adhesion_available_from_phase_lower_bound": a["adhesion_available_lower_bound"],
            "adhesion_available_from_phase_determined": a["adhesion_available_determined"],
            "mu0_from_phase": a["mu0"], "mu0_from_phase_low": a["mu0_low"],
            "mu0_from_phase_high": a["mu0_high"],
            "probe_depth_needed_from_phase": a["probe_depth_needed"],
            "phase_fit_best_law": a["best_law"],
            "mu_from_phase_constant_source": getattr(pfit, "constant_source", "") or None}


def curve_check(polach, creepage_limit: float, *, n: int = 2000) -> tuple[bool, str | None]:
    """Whether the fitted creep curve rises monotonically from zero creepage to its maximum.

    A physical creep curve does; a dip before the peak means the optimiser's answer is not a
    usable curve.

    Parameters
    ----------
    polach : PolachFit
        The force fit.
    creepage_limit : float
        Upper end of the creepage range checked [-].
    n : int
        Grid points over ``[0, creepage_limit]`` [-]. Default 2000.

    Returns
    -------
    ok : bool
        The curve is usable.
    problem : str or None
        What is wrong, or None.
    """
    grid = np.linspace(0.0, float(creepage_limit), n)
    coa = np.asarray(polach.curve(grid), dtype=float)
    if not np.all(np.isfinite(coa)):
        return False, "the fitted curve is not finite on the creepage range"
    top = int(np.argmax(coa))
    if top == 0:
        return False, "the fitted curve does not rise from zero creepage"
    tol = 1e-9 * max(float(coa[top]), 1e-12)
    falls = np.flatnonzero(np.diff(coa[: top + 1]) < -tol)
    if falls.size:
        return False, (f"the fitted curve falls at creepage {grid[falls[0]]:.3g} before its "
                       f"maximum CoA {coa[top]:.4f} at creepage {grid[top]:.3g}")
    return True, None


@dataclass
class Analysis:
    """The fit stage's result (:func:`torquemod.analyze`).

    ``polach`` the force fit (:class:`torquemod.analysis.polachfitresult.PolachFit`, None
    with the reason in ``polach_skipped``), ``phase_fit`` mu from the phase
    (:class:`torquemod.analysis.phasefit.PhaseMuFit`,
    None with ``phase_fit_skipped``), ``theory`` the rigid-wheel check, ``onset`` the
    saturation onset, ``steps`` the steps table with the analysis columns, ``used`` which of
    ``points`` entered the Polach fit (not slipping), ``options`` the
    :class:`~torquemod.analysis.analyzer.FitOptions`. ``saturation_torque_nm`` is ``Ts = mu*N*Rw``
    with
    the mu named by ``saturation_torque_source`` ("forces", "phase"; None when neither fit
    determines mu); it is the one Ts of every table and figure. Torques [N*m], loads [N],
    radii [m].

    Attributes
    ----------
    options : FitOptions
        The options the fit ran with.
    steps : pandas.DataFrame
        The steps table plus ``torque_pct_saturation`` [%], ``creep_coefficient`` k [-],
        ``phase_theory_deg`` and ``phase_fit_deg`` [deg], ``utilisation_phase`` [-].
    points : CreepPoints
        Creep-curve points per step: creepage [-], CoA [-], phase [deg].
    used : ndarray of bool
        Which ``points`` entered the Polach fit (not slipping).
    polach : PolachFit or None
        The force fit (Polach 2005, Eqs. 3, 8 and 9); None with the reason in
        ``polach_skipped``.
    polach_skipped : str or None
        Why there is no force fit (no forces recorded, too few points, ...); None when
        there is one.
    phase_fit : PhaseMuFit or None
        The available adhesion from the phases; None with the reason in
        ``phase_fit_skipped``.
    phase_fit_skipped : str or None
        Why there is no fit from the phases; None when there is one.
    theory : TheoryCheck
        Measured against rigid-wheel phases ``atan(C/k)`` (the V-Track paper, Eq. 1).
    phase_theory_deg : ndarray
        The rigid-wheel phase per step [deg].
    theory_rig : dict or None
        ``wheel_inertia_kg_m2`` [kg m^2] and ``wheel_radius_m`` [m] behind C when the rig
        gives them.
    onset : OnsetResult
        The saturation onset.
    saturation_torque_nm, saturation_torque_stderr_nm : float or None
        ``Ts = mu*N*Rw`` [N*m] and its standard error [N*m].
    normal_load_n : float
        Nominal normal load N [N].
    wheel_radius_m : float
        Wheel rolling radius Rw [m].
    stiffness : float or None
        Lumped contact stiffness ``s`` [-] (Polach 2005, Eq. 3) when known.
    speed_m_s : float or None
        Mean rolling speed [m/s].
    warnings : list of str
        What the caller should know.
    created_utc : str
        ISO 8601 time of the analysis (UTC).
    source : dict
        The processing run behind it (version, time, manifest).
    name : str
        The experiment's name.
    saturation_torque_source : {"forces", "phase"} or None
        Which fit's mu gives ``saturation_torque_nm``.

    References
    ----------
    .. [1] O. Polach, "Creep forces in simulations of traction vehicles running on adhesion
       limit", Wear 258 (2005) 992-1000.
    .. [2] "Experimental Validation of the Torque-Modulation-Based Method for Train-Borne
       Coefficient of Friction Measurement" (TU Delft, V-Track rig), Eq. (1).
    """

    options: FitOptions
    steps: pd.DataFrame
    points: CreepPoints
    used: np.ndarray
    polach: PolachFit | None
    polach_skipped: str | None
    phase_fit: PhaseMuFit | None
    phase_fit_skipped: str | None
    theory: TheoryCheck
    phase_theory_deg: np.ndarray
    theory_rig: dict | None
    onset: OnsetResult
    saturation_torque_nm: float | None
    saturation_torque_stderr_nm: float | None
    normal_load_n: float
    wheel_radius_m: float
    stiffness: float | None
    speed_m_s: float | None
    warnings: list[str] = field(default_factory=list)
    created_utc: str = ""
    source: dict = field(default_factory=dict)
    name: str = ""
    saturation_torque_source: str | None = None  # "forces", "phase" or None

    # --- headline numbers -------------------------------------------------------------------
    @property
    def mu(self) -> float | None:
        """mu from the force fit [-]; None when not determined or skipped."""
        return None if self.polach is None else self.polach.mu

    @property
    def mu_stderr(self) -> float | None:
        return None if self.polach is None else self.polach.mu_stderr

    @property
    def mu_determined(self) -> bool:
        return self.mu is not None

    @property
    def mu_lower_bound(self) -> float | None:
        """What the points show at least: the fit's bound, or the highest fitted CoA."""
        if self.polach is not None:
            return float(self.polach.mu_lower_bound)
        coa = self.points.coa[self.used]
        coa = coa[np.isfinite(coa)]
        return float(coa.max()) if coa.size else None

    @property
    def mu_from_phase(self) -> float | None:
        return None if self.phase_fit is None else self.phase_fit.mu

    @property
    def curve_ok(self) -> tuple[bool | None, str | None]:
        """(fitted curve rises monotonically to its peak, what is wrong); (None, None)
        without a Polach fit."""
        if self.polach is None:
            return None, None
        return curve_check(self.polach, self.options.creepage_limit)

    @property
    def converged(self) -> bool | None:
        """The optimiser converged and the fitted curve is a usable creep curve."""
        if self.polach is None:
            return None
        return bool(self.polach.converged) and bool(self.curve_ok[0])

    @property
    def theory_difference(self) -> tuple[float | None, float | None]:
        """RMS and maximum |measured - theory| phase [deg] over the steps."""
        diff = self.points.phase_deg - self.phase_theory_deg
        ok = np.isfinite(diff)
        if not ok.any():
            return None, None
        return float(np.sqrt(np.mean(diff[ok] ** 2))), float(np.max(np.abs(diff[ok])))

    # --- documents --------------------------------------------------------------------------
    def step_records(self) -> list[dict]:
        """One dict per step (the ``steps`` list of fit.json)."""
        pts, s = self.points, self.steps.set_index("step").reindex(self.points.step)
        return [{"step": int(st), "dc_torque_nm": float(t), "creepage": float(x),
                 "coa": float(c), "phase_deg": float(p), "phase_std_deg": float(ps),
                 "phase_theory_deg": float(pt), "creep_coefficient": float(kk),
                 "torque_pct_saturation": float(q), "slip": not bool(u),
                 "phase_fit_deg": float(pf), "utilisation_phase": float(up)}
                for st, t, x, c, p, ps, pt, kk, q, u, pf, up in zip(
                    pts.step, pts.dc_torque_nm, pts.creepage, pts.coa, pts.phase_deg,
                    pts.phase_std_deg, self.phase_theory_deg, s["creep_coefficient"],
                    s["torque_pct_saturation"], self.used, s["phase_fit_deg"],
                    s["utilisation_phase"], strict=True)]

    def to_dict(self, *, results_dir: str | None = None) -> dict:
        """The ``fit.json`` document (strict-JSON ready)."""
        if self.polach is not None:
            fit_dict = self.polach.to_dict()
        else:
            fit_dict = {"mu": None, "mu_stderr": None, "mu_determined": False,
                        "mu_lower_bound": self.mu_lower_bound, "converged": None}
        fit_dict["fit_skipped"] = self.polach_skipped
        fit_dict["converged"] = self.converged
        ok, problem = self.curve_ok
        fit_dict["curve_monotone"], fit_dict["curve_problem"] = ok, problem
        fit_dict.update(phase_keys(self.phase_fit))
        theory = self.theory.to_dict()
        if self.theory_rig is not None:
            theory["rig"] = dict(self.theory_rig)
        theory["rms_difference_deg"], theory["max_abs_difference_deg"] = self.theory_difference
        given = self.stiffness is not None
        return to_jsonable({
            **fit_dict,
            "saturation_torque_nm": self.saturation_torque_nm,
            "saturation_torque_stderr_nm": self.saturation_torque_stderr_nm,
            "saturation_torque_source": self.saturation_torque_source,
            "normal_load_n": self.normal_load_n, "wheel_radius_m": self.wheel_radius_m,
            "theory": theory, "onset": self.onset.to_dict(), "steps": self.step_records(),
            "warnings": list(self.warnings),
            "fit_options": dataclasses.asdict(self.options),
            "torquemod_version": __version__, "created_utc": self.created_utc,
            "source": {"results_dir": results_dir, **self.source},
            "identifiability": "only mu, kA*s and kS*s are identifiable (s = pi*G*a*b*c11/"
                               "(4*Q)); " + ("kA, kS reported with the given s" if given
                                             else "the products are reported"),
        })

    def summary(self) -> dict:
        """The headline numbers as a JSON-ready dict (what the CLI prints)."""
        doc = self.to_dict()
        theory = doc["theory"]
        return to_jsonable({
            "mu": self.mu, "mu_stderr": self.mu_stderr, "mu_determined": self.mu_determined,
            "mu_lower_bound": self.mu_lower_bound, "curve_peak_coa": doc.get("curve_peak_coa"),
            "fit_skipped": self.polach_skipped, **phase_keys(self.phase_fit),
            "saturation_torque_nm": self.saturation_torque_nm,
            "saturation_torque_stderr_nm": self.saturation_torque_stderr_nm,
            "saturation_torque_source": self.saturation_torque_source,
            "onset_step": self.onset.step, "theory_mode": self.theory.mode,
            "theory_rms_deg": theory["rms_difference_deg"],
            "theory_max_deg": theory["max_abs_difference_deg"], "converged": self.converged,
            "steps": doc["steps"], "warnings": list(self.warnings)})

    # --- text -------------------------------------------------------------------------------
    def report(self) -> str:
        """A plain-text report: mu from both estimates, Ts, the onset, the theory check,
        the fit details and the warnings."""
        lines = [f"[[Analysis]] {self.name}: {len(self.points)} steps "
                 f"({int(self.used.sum())} in the force fit)"]
        lines += ["  " + line for line in headline_lines(self)]
        shown = set()  # each warning once: the fits' own reports list theirs
        if self.polach is not None:
            lines.append(self.polach.report())
            shown.update(self.polach.warnings)
        if self.phase_fit is not None:
            lines.append(self.phase_fit.report())
            shown.update(f"mu from the phase: {w}" for w in self.phase_fit.warnings)
        lines += [f"WARNING: {w}" for w in self.warnings if w not in shown]
        return "\n".join(lines)

    def __repr__(self) -> str:
        mu = f"mu={self.mu:.4f}+-{self.mu_stderr:.4f}" if self.mu is not None else \
            f"mu>={_f(self.mu_lower_bound)} (not determined)"
        mp = self.mu_from_phase
        return (f"<Analysis {self.name!r}: {mu}, mu from phase="
                f"{'-' if mp is None else f'{mp:.4f}'}, onset step {self.onset.step}, "
                f"{len(self.warnings)} warnings>")

    def _repr_html_(self) -> str:
        items = "".join(f"<li>{escape(line)}</li>" for line in headline_lines(self))
        return f"<p>{escape(repr(self))}</p><ul>{items}</ul>"

    # --- figures ----------------------------------------------------------------------------
    def plot_creep_curve(self, *, ax=None, coa_multiplier: float = 20.0,
                         creepage_multiplier: float = 5.0):
        """Paper Figure 3 on ``ax``, returned; without one on a new Figure (not pyplot),
        whose Axes is returned."""
        from torquemod.analysis.figures import creep_curve_figure
        return creep_curve_figure(self, ax=ax, coa_multiplier=coa_multiplier,
                                  creepage_multiplier=creepage_multiplier)

    def plot_phase(self, *, ax=None):
        """Paper Figure 4 (phase against DC torque, % of Ts, with the theory) on ``ax``;
        returns the Axes (a new Figure's when None)."""
        from torquemod.analysis.figures import phase_figure
        return phase_figure(self, ax=ax)

    def plot_phase_fit(self, *, ax=None):
        """The phase against the utilised adhesion with the fit giving mu from the phase;
        returns the Axes (a new Figure's when None)."""
        from torquemod.analysis.figures import phase_fit_figure
        return phase_fit_figure(self, ax=ax)


def _f(x, spec: str = ".4f") -> str:
    return "-" if x is None or not np.isfinite(x) else format(x, spec)


def headline_lines(ana: Analysis) -> list[str]:
    """The few lines every summary shows (CLI, report(), notebooks).

    Parameters
    ----------
    ana : Analysis
        The analysis.

    Returns
    -------
    list of str
        The lines.
    """
    out = []
    if ana.polach_skipped:
        out.append(f"Polach fit skipped: {ana.polach_skipped}")
    elif ana.mu is not None:
        out.append(f"Polach fit: mu = {ana.mu:.4f} +- {ana.mu_stderr:.4f}, saturation torque "
                   f"Ts = {ana.saturation_torque_nm:.2f} N*m")
    else:
        out.append(f"Polach fit: mu not determined by these points; mu >= "
                   f"{_f(ana.mu_lower_bound)}")
    ok, problem = ana.curve_ok
    if ok is False:
        out.append(f"Polach fit not usable: {problem}")
    pf = ana.phase_fit
    if pf is not None and pf.mu_determined:
        lo, hi = pf.mu_interval_95
        ts = (f"; saturation torque Ts = {ana.saturation_torque_nm:.2f} N*m"
              if ana.saturation_torque_source == "phase" else "")
        out.append(f"available adhesion from the phase: {pf.mu:.4f} (95 % interval {_f(lo)} "
                   f".. {_f(hi)}){ts}")
    elif pf is not None:
        a = pf.adhesion
        rng = f" (95 % range {_f(a.low)} .. {_f(a.high)})" if a.closed else ""
        depth = (f"; a step at {100 * a.probe_depth:.0f} % of it would determine it"
                 if np.isfinite(a.probe_depth) else "")
        out.append(f"available adhesion from the phase: not determined by these steps; >= "
                   f"{_f(pf.mu_interval_95[0])}{rng}{depth}")
    onset = f"step {ana.onset.step}" if ana.onset.step is not None else "not reached"
    rms = ana.theory_difference[0]
    out.append(f"saturation onset: {onset}; theory vs measured phase: RMS {_f(rms, '.2f')} deg")
    return out


# --- saving and reading back ----------------------------------------------------------------
def saved_state(ana: Analysis) -> dict:
    """What :func:`from_saved` needs besides the ``fit.json`` document and the steps table.

    Parameters
    ----------
    ana : Analysis
        The analysis.

    Returns
    -------
    dict
        The few values ``fit.json`` (:meth:`Analysis.to_dict`) does not hold, JSON-ready.
    """
    return to_jsonable({
        "polach_converged": None if ana.polach is None else bool(ana.polach.converged),
        "polach_mu_stderr_estimate": None if ana.polach is None
        else str(float(ana.polach.mu_stderr_estimate)),  # text keeps inf (float() reads it)
        "polach_warnings": None if ana.polach is None else list(ana.polach.warnings),
        "phase_fit": None if ana.phase_fit is None else ana.phase_fit.state(),
        "phase_fit_skipped": ana.phase_fit_skipped, "stiffness": ana.stiffness,
        "speed_m_s": ana.speed_m_s, "onset_index": ana.onset.index})


def from_saved(doc: dict, state: dict, steps: pd.DataFrame, options: FitOptions, *,
               name: str = "") -> Analysis:
    """The :class:`Analysis` back from what :func:`torquemod.save` wrote, without fitting again.

    Parameters
    ----------
    doc : dict
        The ``fit.json`` document.
    state : dict
        The :func:`saved_state` of the analysis.
    steps : pandas.DataFrame
        The analysed steps table (``steps.csv``).
    options : FitOptions
        The options the fit ran with.
    name : str
        The experiment's name. Default "".

    Returns
    -------
    Analysis
        Equal to the one saved.

    Raises
    ------
    KeyError, TypeError, ValueError
        The document, the state and the steps do not fit together (the loader turns these
        into an InputError naming fit.json).
    """
    from torquemod.analysis.creep import creep_points
    from torquemod.analysis.phasefitresult import PhaseMuFit
    from torquemod.analysis.polachfitresult import PolachFit

    def num(x):
        return np.nan if x is None else float(x)

    pts = creep_points(steps.drop(columns=[c for c in _ADDED if c in steps]))
    recs = doc["steps"]
    if [r["step"] for r in recs] != [int(s) for s in pts.step]:
        raise ValueError("fit.json steps differ from steps.csv")
    used = np.array([not r["slip"] for r in recs], dtype=bool)
    polach = None
    if "theta_internal" in doc:
        polach = PolachFit.from_dict(doc, converged=state["polach_converged"],
                                     mu_stderr_estimate=state["polach_mu_stderr_estimate"],
                                     warnings=state["polach_warnings"])
    pfit = None if state["phase_fit"] is None else PhaseMuFit.from_state(state["phase_fit"])
    th = doc["theory"]
    k = np.array([num(r["creep_coefficient"]) for r in recs])
    theory_deg = np.array([num(r["phase_theory_deg"]) for r in recs])
    c = th["constant"]
    const = np.broadcast_to(np.array(c, dtype=float), theory_deg.shape).copy()
    diff = pts.phase_deg - theory_deg
    theory = TheoryCheck(th["mode"], const, num(th["constant_stderr"]), k, pts.phase_deg,
                         theory_deg, diff, num(th["rms_difference_deg"]),
                         num(th["max_abs_difference_deg"]), int(th["n_steps_compared"]))
    o = doc["onset"]
    onset = OnsetResult(step=o["step"], index=state["onset_index"], criterion=o["criterion"],
                        threshold_deg=num(o["threshold_deg"]),
                        pooled_phase_std_deg=num(o["pooled_phase_std_deg"]),
                        phase_jumps_deg=list(o["phase_jumps_deg"]),
                        creep_coefficient_ratios=list(o["creep_coefficient_ratios"]),
                        parameters=dict(o["parameters"]), tan_ratios=list(o["tan_ratios"]))
    source = {k_: v for k_, v in doc["source"].items() if k_ != "results_dir"}
    return Analysis(
        options=options, steps=steps, points=pts, used=used, polach=polach,
        polach_skipped=doc["fit_skipped"], phase_fit=pfit,
        phase_fit_skipped=state["phase_fit_skipped"], theory=theory,
        phase_theory_deg=theory_deg, theory_rig=th.get("rig"), onset=onset,
        saturation_torque_nm=doc["saturation_torque_nm"],
        saturation_torque_stderr_nm=doc["saturation_torque_stderr_nm"],
        saturation_torque_source=doc["saturation_torque_source"],
        normal_load_n=float(doc["normal_load_n"]), wheel_radius_m=float(doc["wheel_radius_m"]),
        stiffness=state["stiffness"], speed_m_s=state["speed_m_s"],
        warnings=list(doc["warnings"]), created_utc=str(doc["created_utc"]), source=source,
        name=name)


_ADDED = ("torque_pct_saturation", "creep_coefficient", "phase_theory_deg", "phase_fit_deg",
          "utilisation_phase")
