"""What the commands print: tables of steps and stretches, the fit, warnings, error lines."""

from __future__ import annotations

import argparse
import math
import sys


def fmt(x: object, spec: str) -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        width = spec.split(".")[0]
        return "-".rjust(int(width)) if width.isdigit() else "-"
    return format(x, spec)


def print_steps(steps) -> None:
    """The steps table; with the analysis columns when the steps were analysed."""
    analysed = "torque_pct_saturation" in steps.columns
    print(f"{'step':>4} {'DC [N*m]':>9} {'phase [deg]':>12} {'std':>6} {'creepage':>10} "
          f"{'CoA':>7} {'cycles':>6}" + (f" {'% of Ts':>8} {'theory [deg]':>13}"
                                          if analysed else ""))
    for r in steps.itertuples():
        extra = (f" {fmt(r.torque_pct_saturation, '8.1f')} "
                 f"{fmt(r.phase_theory_deg, '13.2f')}") if analysed else ""
        print(f"{r.step:>4} {r.dc_torque_nm:>9.2f} {fmt(r.phase_deg, '12.3f')} "
              f"{fmt(r.phase_std_deg, '6.3f')} {fmt(r.creepage, '10.3e')} "
              f"{fmt(r.coa, '7.4f')} {r.n_cycles:>6}{extra}"
              + ("  SLIP (not fitted)" if getattr(r, "slip", False) else ""))


def stage_printer(args: argparse.Namespace):
    """Stage lines on stderr (silent with --quiet)."""
    if getattr(args, "quiet", False):
        return None
    return lambda text: print(text, file=sys.stderr, flush=True)


def print_warnings(warnings) -> None:
    for w in warnings:
        print(f"warning: {w}", file=sys.stderr)


def print_fit(ana) -> None:
    """The analysis' headline lines, formatted (a skipped fit goes to stderr)."""
    from torquemod.analysis.result import headline_lines
    for line in headline_lines(ana):
        if line.startswith(("Polach fit skipped", "Polach fit not usable")):
            print(f"warning: {line}", file=sys.stderr)
        else:
            print(line)


def print_stretches(seg) -> None:
    """The along-track table per segment, one line each: span, condition, mu or bound."""
    print(f"  {'span [m]':>13} {'condition (guess)':>20} {'mu':>6} {'95 % interval':>13} "
          f"{'bound':>6}")
    for _, s in seg.iterrows():
        interval = (f"{s.mu_low_95:.3f}-{s.mu_high_95:.3f}" if s.mu_high_95 == s.mu_high_95
                    else "")
        print(f"  {s.start_m:6.0f}-{s.end_m:<6.0f} {s.condition:>20} {fmt(s.mu, '6.3f')} "
              f"{interval:>13} {fmt(s.mu_lower_bound, '6.3f')}")


def print_train_demo(train: dict) -> None:
    print()
    print(f"train run:     {train['run']}")
    print(f"train report:  {train['report']}")
    print(f"{'segment':>18} {'span [m]':>12} {'friction':>9} {'available':>9} {'mu est.':>9} "
          f"{'lower bd':>9}")
    for s in train["segments"]:
        print(f"{s['condition']:>18} {s['start_m']:5.0f}-{s['end_m']:<6.0f} {s['mu']:9.3f} "
              f"{s['adhesion_peak']:9.3f} {fmt(s['mu_estimate'], '9.3f')} "
              f"{fmt(s['mu_lower_bound'], '9.3f')}")
    print("friction: the twin's mean friction; available: its available adhesion (the creep "
          "curve's peak), what 'mu est.' and 'lower bd' estimate. Where mu is not determined "
          "(the axle stayed far from saturation for the curve's shape to fix it), the lower "
          "bound is what the data show.")


def why_they_differ(out: dict, truth: dict) -> str:
    """Why the fitted mu is not the simulator's peak CoA, in the numbers of this run."""
    if out.get("mu") is not None:
        head = f"why mu from the forces ({out['mu']:.4f}) differs"
    elif out.get("mu_from_phase") is not None:  # the fit from the phase estimates the peak
        return (f"the available adhesion from the phase ({out['mu_from_phase']:.4f}) "
                f"estimates the creep curve's peak CoA ({truth['peak_coa']:.4f}) itself.")
    else:  # neither fit determines mu: only a lower bound is known, the higher of the two
        bounds = [b for b in (out.get("mu_lower_bound"),
                              (out.get("mu_from_phase_interval_95") or [None])[0])
                  if b is not None]
        bound = max(bounds) if bounds else None
        return (f"mu is not determined by these steps (mu >= {fmt(bound, '.4f')}): their "
                "points do not fix the creep curve's shape near saturation (too few cycles "
                "per step, or steps too far below saturation). The simulated curve peaks at "
                f"CoA {truth['peak_coa']:.4f}, below the friction (mu0 = {truth['mu0']:.4f}, "
                f"{truth['mu_at_top_step']:.4f} at the top step's slip velocity).")
    head += f" from the peak CoA ({truth['peak_coa']:.4f}): "
    return (head + "mu is the friction coefficient of the fitted Polach curve, the level its "
            "CoA would reach only at full sliding; a creep curve with a finite kA/kS peaks "
            "below its mu, and the simulator's friction also falls with the slip velocity "
            f"(from mu0 = {truth['mu0']:.4f} to {truth['mu_at_top_step']:.4f} at the top "
            "step), so the simulated curve's maximum lies below both. Compare mu with the "
            "friction at the top step's slip velocity, not with the peak CoA.")


def one_line(exc: BaseException) -> str:
    """The message on one line, in the command line's words: the library's keyword
    ``force=True`` is the option ``--force`` here."""
    text = " ".join(str(exc).split())
    return text.replace("pass force=True", "use --force").replace("force=True", "--force")


def os_error_line(exc: OSError, args: argparse.Namespace) -> str:
    """``path: reason`` for an OSError of the system: the file it names, else the command's
    output (``--out`` or the results folder)."""
    path = exc.filename or getattr(args, "out", None) or getattr(args, "results", None)
    reason = exc.strerror or one_line(exc)
    return f"{path}: {reason}" if path else reason
