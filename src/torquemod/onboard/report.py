"""Figures and the HTML report of an on-board run. Every plot takes an ``ax``."""

from __future__ import annotations

import base64
import html
import io
from pathlib import Path

import numpy as np


def plot_mu(result, ax=None):
    """mu with its 95 % interval (or the lower bound) along the track; truth overlaid."""
    import matplotlib.pyplot as plt
    ax = ax or plt.gca()
    t = result.track
    x = t["position_m"].to_numpy()
    ax.fill_between(x, t["mu_low_95"], t["mu_high_95"], color="C0", alpha=0.25, lw=0,
                    label="95 % interval")
    ax.plot(x, t["mu"], "C0", lw=1.5, label="mu from the phase")
    und = t["mu"].isna()
    ax.plot(x[und], t["mu_low_95"][und], ".", color="C1", ms=2,
            label="lower bound (mu not determined)")
    ax.plot(x, t["coa"], color="0.5", lw=0.6, label="CoA (utilised adhesion)")
    if result.truth is not None:
        tr = result.truth
        ax.plot(tr["position_m"], tr["mu"], "k--", lw=1, label="truth: friction")
        ax.plot(tr["position_m"], tr["adhesion_peak"], "k:", lw=1,
                label="truth: available adhesion")
    ax.set_xlabel("position [m]")
    ax.set_ylabel("coefficient [-]")
    ax.legend(fontsize=7, loc="upper right")
    return ax


def plot_phase(result, ax=None):
    """The lag of the axle speed behind the torque per window, with +-2 standard errors."""
    import matplotlib.pyplot as plt
    ax = ax or plt.gca()
    t = result.track
    x = t["position_m"]
    ax.fill_between(x, t["phase_deg"] - 2 * t["phase_se_deg"],
                    t["phase_deg"] + 2 * t["phase_se_deg"], color="C2", alpha=0.3, lw=0)
    ax.plot(x, t["phase_deg"], "C2", lw=0.8)
    ax.set_xlabel("position [m]")
    ax.set_ylabel("phase lag [deg]")
    return ax


def plot_utilisation(result, ax=None):
    """Utilisation CoA/mu where mu is given, the flags; the true utilisation overlaid."""
    import matplotlib.pyplot as plt
    ax = ax or plt.gca()
    t = result.track
    x = t["position_m"].to_numpy()
    ax.plot(x, t["utilisation"], "C0", lw=1, label="CoA / mu (estimated)")
    if result.truth is not None:
        ax.plot(result.truth["position_m"], result.truth["coa"] / result.truth["mu"], "k--",
                lw=0.8, label="truth: CoA / friction")
    low = t["low_adhesion"].to_numpy()
    slip = t["slip"].to_numpy()
    ax.plot(x[low], np.full(low.sum(), 1.02), "|", color="C3", label="low_adhesion")
    ax.plot(x[slip], np.full(slip.sum(), 1.06), "|", color="k", label="slip")
    ax.set_ylim(0, 1.1)
    ax.set_xlabel("position [m]")
    ax.set_ylabel("utilisation [-]")
    ax.legend(fontsize=7, loc="lower right")
    return ax


FIGURES = {"mu_along_track.png": plot_mu, "phase_along_track.png": plot_phase,
           "utilisation_along_track.png": plot_utilisation}


def write_figures(folder: Path, result) -> dict[str, bytes]:
    """Save :data:`FIGURES` as PNG in ``folder``; return their bytes for the report."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    out = {}
    for name, fn in FIGURES.items():
        fig, ax = plt.subplots(figsize=(9, 3.2), layout="constrained")
        fn(result, ax=ax)
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=110)
        plt.close(fig)
        out[name] = buf.getvalue()
        (folder / name).write_bytes(out[name])
    return out


def segment_estimates(track, segments: list[dict]) -> list[dict]:
    """Each truth segment (:func:`torquemod.train.simulate.segment_summary`) with the
    estimate over the track's rows inside it: ``mu_estimate`` (median where mu is given,
    else None), ``mu_lower_bound`` (median of ``mu_low_95``) and ``mu_given_share``."""
    out = []
    for seg in segments:
        part = track[(track.position_m >= seg["start_m"]) & (track.position_m <= seg["end_m"])]
        given = part["mu"].notna()
        out.append({**seg, "mu_estimate": float(part.loc[given, "mu"].median())
                    if given.any() else None,
                    "mu_lower_bound": float(part["mu_low_95"].median()) if len(part)
                    else None, "mu_given_share": float(given.mean()) if len(part) else 0.0})
    return out


def _segments_table(result) -> str:
    tr = result.truth
    if tr is None:
        return ""
    from ..train.simulate import segment_summary
    rows = []
    for s in segment_estimates(result.track, segment_summary(tr)):
        mu = "not determined" if s["mu_estimate"] is None else f"{s['mu_estimate']:.3f}"
        low = "" if s["mu_lower_bound"] is None else f"{s['mu_lower_bound']:.3f}"
        rows.append(f"<tr><td>{html.escape(s['condition'])}</td><td>{s['start_m']:.0f}-"
                    f"{s['end_m']:.0f}</td><td>{s['mu']:.3f}</td>"
                    f"<td>{s['adhesion_peak']:.3f}</td><td>{mu}</td><td>{low}</td>"
                    f"<td>{100 * s['mu_given_share']:.0f} %</td></tr>")
    return ("<h2>Against the simulated truth</h2><table><tr><th>condition</th><th>span [m]"
            "</th><th>friction</th><th>available adhesion</th><th>mu (median)</th>"
            "<th>mu_low_95 (median)</th><th>rows with mu</th></tr>" + "".join(rows)
            + "</table>")


def _delay_sentence(result, s: dict) -> str:
    """What the report says about the torque-speed delay (declared and measured)."""
    v = result.run.vehicle
    declared = (f"declared: torque lag {1e3 * v.torque_lag_s:g} ms, torque delay "
                f"{1e3 * v.torque_delay_s:g} ms, speed delay {1e3 * v.speed_delay_s:g} ms, "
                f"vehicle damping {v.vehicle_damping_n_s_m:g} N*s/m")
    if not result.config.calibrate_delay:
        return f"Sensor dynamics {declared}; no delay measured (calibrate_delay = 0)."
    d = s.get("measured_delay_s", 0.0)
    if d == 0.0:
        return (f"Sensor dynamics {declared}; the run did not determine a further delay "
                "between torque and speed (none taken out).")
    return (f"Sensor dynamics {declared}; a further net delay of the torque behind the "
            f"speed of {1e3 * d:.2f} ms was measured from the run and taken out of the "
            "phase and creep coefficient.")


def write_report(path: Path, result, meta: dict, figures: dict[str, bytes]) -> None:
    """A one-page HTML report: what was run, the summary, the figures, the notes."""
    s = result.summary()
    imgs = "".join(f'<figure><img alt="{html.escape(n)}" src="data:image/png;base64,'
                   f'{base64.b64encode(b).decode()}"><figcaption>{html.escape(n)}'
                   "</figcaption></figure>" for n, b in figures.items())
    notes = "".join(f"<li>{html.escape(n)}</li>" for n in result.notes) or "<li>none</li>"
    v = result.run.vehicle
    body = f"""<!doctype html><html><head><meta charset="utf-8">
<title>torquemod on-board: {html.escape(result.run.manifest_path.name)}</title>
<style>body{{font-family:sans-serif;max-width:60em;margin:2em auto}}
table{{border-collapse:collapse}}td,th{{border:1px solid #bbb;padding:2px 8px}}
img{{max-width:100%}}</style></head><body>
<h1>Friction along the run</h1>
<p>Run {html.escape(str(result.run.manifest_path))}, axle {result.axle}: wheel radius
{v.wheel_radius_m} m, axle load {v.normal_load_n:.0f} N, inertia {v.inertia_kg_m2} kg m²;
modulation {result.run.modulation_frequency_hz} Hz, {result.run.modulation_amplitude_nm} N m.
torquemod {html.escape(meta['torquemod_version'])}.</p>
<p>{s['windows']} windows over {s['length_m']:.0f} m, measurable (the torque modulated,
the train rolling forward) in {100 * s.get('measurable_share', 1.0):.0f} %; mu determined in
{100 * s['mu_given_share']:.0f} % of them (elsewhere only a lower bound: the data do not fix
mu when the axle works far from saturation); low adhesion flagged in
{100 * s['low_adhesion_share']:.1f} %, slip in {100 * s['slip_share']:.1f} %.</p>
<p>{_delay_sentence(result, s)}</p>
{_segments_table(result)}
<h2>Figures</h2>{imgs}
<h2>Notes</h2><ul>{notes}</ul>
<h2>Settings</h2><pre>{html.escape(str(meta['onboard']))}</pre>
</body></html>"""
    path.write_text(body, encoding="utf-8")
