# PYTHON_ARGCOMPLETE_OK
"""The ``torquemod`` command line. The only module that parses arguments or prints.

Every :class:`~torquemod.errors.TorquemodError` ends as one line on stderr and exit code 2;
anything else is a bug: one line, exit code 3, and ``--debug`` shows the traceback. Ctrl-C
ends with 130, SIGTERM with 143. Shell completion comes from argcomplete
(``eval "$(register-python-argcomplete torquemod)"``), loaded only while completing.
"""

from __future__ import annotations

import argparse
import contextlib
import math
import os
import signal
import sys
import threading
from pathlib import Path

from torquemod._util.daskutil import CONNECT_TIMEOUT_S
from torquemod._version import __version__
from torquemod.errors import TorquemodError

EXIT_BAD_INPUT = 2
EXIT_INTERNAL = 3
EXIT_INTERRUPTED = 130  # 128 + SIGINT, as a shell reports Ctrl-C
EXIT_TERMINATED = 143  # 128 + SIGTERM
EXIT_BROKEN_PIPE = 141  # 128 + SIGPIPE, as a shell reports `torquemod ... | head`


def _fmt(x: object, spec: str) -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        width = spec.split(".")[0]
        return "-".rjust(int(width)) if width.isdigit() else "-"
    return format(x, spec)


def _print_steps(steps) -> None:
    """The steps table; with the analysis columns when the steps were analysed."""
    analysed = "torque_pct_saturation" in steps.columns
    print(f"{'step':>4} {'DC [N*m]':>9} {'phase [deg]':>12} {'std':>6} {'creepage':>10} "
          f"{'CoA':>7} {'cycles':>6}" + (f" {'% of Ts':>8} {'theory [deg]':>13}"
                                          if analysed else ""))
    for r in steps.itertuples():
        extra = (f" {_fmt(r.torque_pct_saturation, '8.1f')} "
                 f"{_fmt(r.phase_theory_deg, '13.2f')}") if analysed else ""
        print(f"{r.step:>4} {r.dc_torque_nm:>9.2f} {_fmt(r.phase_deg, '12.3f')} "
              f"{_fmt(r.phase_std_deg, '6.3f')} {_fmt(r.creepage, '10.3e')} "
              f"{_fmt(r.coa, '7.4f')} {r.n_cycles:>6}{extra}"
              + ("  SLIP (not fitted)" if getattr(r, "slip", False) else ""))


def _stage_printer(args: argparse.Namespace):
    """Stage lines on stderr (silent with --quiet)."""
    if getattr(args, "quiet", False):
        return None
    return lambda text: print(text, file=sys.stderr, flush=True)


def _print_warnings(warnings) -> None:
    for w in warnings:
        print(f"warning: {w}", file=sys.stderr)


def _print_fit(ana) -> None:
    """The analysis' headline lines, formatted (a skipped fit goes to stderr)."""
    from torquemod.analysis.result import headline_lines
    for line in headline_lines(ana):
        if line.startswith(("Polach fit skipped", "Polach fit not usable")):
            print(f"warning: {line}", file=sys.stderr)
        else:
            print(line)


def cmd_process(args: argparse.Namespace) -> int:
    from torquemod.api import run

    out = run(args.experiment, args.out, phase_method=args.phase_method,
              nan_policy=args.nan_policy, fit=not args.no_fit, force=args.force,
              report_options=_pdf_option(args),
              progress=not args.quiet, command=sys.argv, on_stage=_stage_printer(args),
              export=args.export)
    res, ana = out.result, out.analysis
    _print_warnings(res.warnings + (ana.warnings if ana is not None else []))
    _print_steps(ana.steps if ana is not None else res.steps)
    if ana is not None:
        _print_fit(ana)
    t = out.stage_s
    print(f"done in {t['total']:.1f} s: processing {len(res.cycles)} cycles "
          f"{t['process']:.1f} s ({res.timing_s['workers']} threads), fit {t['fit']:.1f} s, "
          f"writing results{' and report' if ana is not None else ''} {t['write']:.1f} s")
    print(f"results: {out.folder}")
    if out.report is not None:
        print(f"report:  {out.report}")
        _print_pdf(args, out.report)
    return 0


def _train_config(args: argparse.Namespace):
    """The train configuration when --train is given or the config says kind = "train"."""
    import tomllib

    if args.train:
        from torquemod.twins.train import load_train_config
        return load_train_config(args.config)
    if args.config:
        try:
            doc = tomllib.loads(Path(args.config).read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError):
            return None  # the rig's loader names the problem
        # torquemod.twins.train.is_train_config, without importing the train twin for a rig config
        if doc.get("kind") == "train":
            from torquemod.twins.train import config_from_dict
            return config_from_dict(doc, where=str(args.config))
    return None


def cmd_simulate_train(args: argparse.Namespace, config) -> int:
    from torquemod.twins.train import run_train_simulation
    say = _stage_printer(args)
    if say:
        say("simulating the train run (the first run compiles the twin's numba kernels) ...")
    from torquemod.errors import InputError, ProcessingError
    try:
        summary = run_train_simulation(config, Path(args.out), seed=args.seed,
                                       force=args.force)
    except ProcessingError as exc:  # the twin could not run this configuration: name it
        raise InputError(str(exc), path=args.config or "the default train config") from None
    print(f"train run written to {args.out}/run.toml (MDF4) and run_h5.toml (HDF5), truth in "
          "truth.parquet")
    print(f"  {summary['length_m']:.0f} m in {summary['duration_s']:.1f} s")
    for seg in summary["segments"]:
        print(f"  {seg['condition']:>18} {seg['start_m']:7.0f}-{seg['end_m']:7.0f} m: friction "
              f"{seg['mu']:.3f}, available adhesion {seg['adhesion_peak']:.3f}, max "
              f"utilisation {seg['max_utilisation']:.2f}")
    return 0


def cmd_onboard(args: argparse.Namespace) -> int:
    from torquemod import api
    from torquemod.ontrain.folder import check_onboard_out, save_onboard
    from torquemod.results.export import check_formats
    export = check_formats(args.export)  # a bad format is refused before the work
    say = _stage_printer(args)
    run = api.read_run(args.run)
    check_onboard_out(run, args.out, force=args.force)  # an occupied --out: before the work
    if say:
        say("estimating the friction along the run ...")
    results = [api.onboard(run, axle=e.axle) for e in run.recordings]
    save_onboard(results, Path(args.out), force=args.force, command=sys.argv, export=export)
    _print_warnings([w for r in results for w in r.warnings])
    for r in results:
        s = r.summary()
        print(f"axle {s['axle']}: {s['windows']} windows over {s['length_m']:.0f} m, mu "
              f"determined in {100 * s['mu_given_share']:.0f} % (elsewhere a lower bound), "
              f"measurable in {100 * s['measurable_share']:.0f} %, "
              f"low adhesion {100 * s['low_adhesion_share']:.1f} %, slip "
              f"{100 * s['slip_share']:.1f} %; {s['seconds']:.1f} s")
        _print_stretches(r.along_track())
    print(f"track:  {Path(args.out) / 'track.parquet'}"
          + (f" (also as {', '.join('track.' + f for f in export)})" if export else ""))
    print(f"along the track: {Path(args.out) / 'along_track.csv'} (per segment), "
          "along_track_km.csv (per km)")
    print(f"report: {Path(args.out) / 'report.html'}")
    _write_pdf(args, Path(args.out) / "report.html")
    return 0


def _print_stretches(seg) -> None:
    """The along-track table per segment, one line each: span, condition, mu or bound."""
    print(f"  {'span [m]':>13} {'condition (guess)':>20} {'mu':>6} {'95 % interval':>13} "
          f"{'bound':>6}")
    for _, s in seg.iterrows():
        interval = (f"{s.mu_low_95:.3f}-{s.mu_high_95:.3f}" if s.mu_high_95 == s.mu_high_95
                    else "")
        print(f"  {s.start_m:6.0f}-{s.end_m:<6.0f} {s.condition:>20} {_fmt(s.mu, '6.3f')} "
              f"{interval:>13} {_fmt(s.mu_lower_bound, '6.3f')}")


def _check_seed(seed: int) -> None:
    if seed < 0:
        raise _UsageError(f"--seed must be 0 or more, got {seed}")


def cmd_simulate(args: argparse.Namespace) -> int:
    if args.print_config and args.train:
        from torquemod.twins.train import default_train_config_text
        sys.stdout.write(default_train_config_text())
        return 0
    if args.print_config:
        from torquemod.twins.vtrack import simulate
        sys.stdout.write(simulate.default_config_text())
        return 0
    if args.out is None:
        raise _UsageError("simulate needs --out DIR (or --print-config)")
    _check_seed(args.seed)
    train = _train_config(args)
    if train is not None:
        return cmd_simulate_train(args, train)
    from torquemod.twins.vtrack import simulate
    config = simulate.load_config(args.config)  # a bad config is one line, before any stage
    say = _stage_printer(args)
    if say:
        say(_COMPILE_NOTE)
    truth = simulate.run_simulation(config, Path(args.out), seed=args.seed, fmt=args.format,
                                    progress=not args.quiet, force=args.force)
    print(f"experiment written to {args.out}/experiment.toml")
    for st in truth.get("steps", []):
        flag = "  SLIP" if st.get("slipped") else ""
        print(f"  step {st['step']}: DC {st['dc_torque_nm']:.2f} N*m, creepage "
              f"{_fmt(st.get('creepage'), '.3e')}, CoA {_fmt(st.get('coa'), '.4f')}, theory "
              f"phase {_fmt(st.get('phase_theory_deg'), '.2f')} deg{flag}")
    return 0


_MAX_POINTS = 2000  # torquemod.sweep.spec.MAX_POINTS (not imported for --help's sake)

_COMPILE_NOTE = ("simulating the experiment (the first run compiles the simulator's numba "
                 "kernels, which can take a minute; later runs reuse the compiled cache) ...")


def _fit_options(args: argparse.Namespace) -> dict:
    """The ``fit`` subcommand's options as FitOptions fields (only those given)."""
    opts = {"velocity_dependent": args.velocity_dependent or None,
            "weighted": False if args.unweighted else None,
            "stiffness": args.stiffness, "inertia_kg_m2": args.inertia,
            "theory_constant": args.theory_constant, "onset_criterion": args.onset_criterion,
            "seed": args.seed}
    return {k: v for k, v in opts.items() if v is not None}


def cmd_fit(args: argparse.Namespace) -> int:
    from torquemod.api import fit_folder
    _, ana = fit_folder(Path(args.results), _fit_options(args),
                        report_options=_pdf_option(args), on_stage=_stage_printer(args))
    _print_warnings(ana.warnings)
    _print_steps(ana.steps)
    _print_fit(ana)
    print(f"updated {args.results}: fit.json, steps.csv, figures and report.html"
          + (" (and report.pdf)" if args.pdf else ""))
    return 0


def cmd_report(args: argparse.Namespace) -> int:
    from torquemod.api import report_folder
    opts = {k: v for k, v in (("step", args.step), ("cycle", args.cycle),
                              ("title", args.title)) if v is not None} | _pdf_option(args)
    path = report_folder(Path(args.results), report_options=opts,
                         on_stage=_stage_printer(args))
    print(f"report written to {path}")
    _print_pdf(args, path)
    return 0


def _pdf_option(args: argparse.Namespace) -> dict:
    """--pdf as the report option that writes report.pdf inside the results folder."""
    return {"pdf": args.pdf_engine} if getattr(args, "pdf", False) else {}


def _print_pdf(args: argparse.Namespace, html_path: Path) -> None:
    if getattr(args, "pdf", False):
        print(f"pdf:     {Path(html_path).with_suffix('.pdf')}")


def _write_pdf(args: argparse.Namespace, html_path: Path) -> None:
    """With --pdf: the report as report.pdf beside it (A4; see torquemod.report.pdf)."""
    if not getattr(args, "pdf", False):
        return
    from torquemod.report.pdf import html_to_pdf
    say = _stage_printer(args)
    if say:
        say(f"writing the PDF ({args.pdf_engine}) ...")
    print(f"pdf:    {html_to_pdf(html_path, engine=args.pdf_engine)}")


def _add_pdf_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--pdf", action="store_true",
                        help="also write the report as report.pdf (A4) beside report.html")
    parser.add_argument("--pdf-engine", choices=["matplotlib", "chromium"],
                        default="matplotlib",
                        help="how the PDF is made: matplotlib (default, always available: "
                             "text, tables and figures laid out on A4) or chromium (a "
                             "headless Chromium on the PATH prints the HTML page)")


def cmd_demo(args: argparse.Namespace) -> int:
    from torquemod.demo import run_demo
    _check_seed(args.seed)
    say = _stage_printer(args)
    out = run_demo(Path(args.out), config_path=args.config, seed=args.seed, force=args.force,
                   progress=not args.quiet, quick=args.quick, on_stage=say,
                   with_train=not args.no_train)
    print(f"simulated experiment: {out['manifest']}")
    print(f"results:              {out['results']}")
    print(f"report:               {out['report']}")
    print()
    print(f"{'step':>4} {'DC [N*m]':>9} {'% of Ts':>8} {'phase [deg]':>12} {'theory [deg]':>13}")
    for st in out.get("steps", []):
        print(f"{st['step']:>4} {st['dc_torque_nm']:>9.2f} "
              f"{_fmt(st.get('torque_pct_saturation'), '8.1f')} "
              f"{_fmt(st.get('phase_deg'), '12.2f')} {_fmt(st.get('phase_theory_deg'), '13.2f')}")
    print()
    _print_warnings(out["analysis"].warnings)
    _print_fit(out["analysis"])
    truth = out.get("truth") or {}
    if truth.get("peak_coa") is not None:
        print(f"simulator truth: mu0 = {truth['mu0']:.4f}, falling with slip velocity to "
              f"{truth['mu_at_top_step']:.4f} at the top step (Polach Eq. 9); creep-curve "
              f"peak CoA {truth['peak_coa']:.4f} at {_fmt(truth.get('peak_torque_nm'), '.2f')} "
              f"N*m; slip at step {truth.get('slip_step')}")
        print(_why_they_differ(out, truth))
    if out.get("train"):
        _print_train_demo(out["train"])
    return 0


def _print_train_demo(train: dict) -> None:
    print()
    print(f"train run:     {train['run']}")
    print(f"train report:  {train['report']}")
    print(f"{'segment':>18} {'span [m]':>12} {'friction':>9} {'available':>9} {'mu est.':>9} "
          f"{'lower bd':>9}")
    for s in train["segments"]:
        print(f"{s['condition']:>18} {s['start_m']:5.0f}-{s['end_m']:<6.0f} {s['mu']:9.3f} "
              f"{s['adhesion_peak']:9.3f} {_fmt(s['mu_estimate'], '9.3f')} "
              f"{_fmt(s['mu_lower_bound'], '9.3f')}")
    print("friction: the twin's mean friction; available: its available adhesion (the creep "
          "curve's peak), what 'mu est.' and 'lower bd' estimate. Where mu is not determined "
          "(the axle stayed far from saturation for the curve's shape to fix it), the lower "
          "bound is what the data show.")


def _why_they_differ(out: dict, truth: dict) -> str:
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
        return (f"mu is not determined by these steps (mu >= {_fmt(bound, '.4f')}): their "
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


def cmd_convert(args: argparse.Namespace) -> int:
    from torquemod.io import convert
    if args.input is None and not args.manifest:
        raise _UsageError("convert needs an INPUT recording or --manifest EXPERIMENT.toml")
    if args.input is None:  # the whole experiment into a folder
        path = convert.convert_experiment(Path(args.manifest), Path(args.out),
                                          force=args.force)
    elif args.manifest:  # one file, read with the manifest's [channels]
        path = convert.convert_listed_file(Path(args.input), Path(args.manifest),
                                           Path(args.out), force=args.force)
    else:
        path = convert.convert_file(Path(args.input), Path(args.out), force=args.force)
    print(f"written {path}")
    return 0


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a positive whole number, got {text!r}")
    return value


def _positive_seconds(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not 0 < value < 1e6:
        raise argparse.ArgumentTypeError(f"expected a positive number of seconds, got {text!r}")
    return value


def cmd_fleet(args: argparse.Namespace) -> int:
    from torquemod.fleet.run import run_fleet
    res = run_fleet(args.runs, Path(args.out), scheduler=args.scheduler,
                    n_workers=args.workers, force=args.force, progress=not args.quiet,
                    revolutions_per_task=args.revolutions_per_task,
                    connect_timeout_s=args.connect_timeout,
                    on_dashboard=lambda link: print(f"dashboard: {link}", file=sys.stderr,
                                                    flush=True))
    print(f"{res.summary.shape[0]} runs: {res.count('processed')} processed, "
          f"{res.count('skipped')} unchanged (skipped), {res.count('failed')} failed "
          f"in {res.wall_s:.1f} s")
    for row in res.failures.itertuples():
        print(f"failed: {getattr(row, 'run', '?')}: {getattr(row, 'message', '')}",
              file=sys.stderr)
    print(f"results: {res.out_dir}")
    if res.report is not None:
        print(f"report:  {res.report}")
    return 0


def cmd_sweep(args: argparse.Namespace) -> int:
    from torquemod._util.daskutil import check_cluster
    from torquemod.sweep.run import plan_line, run_sweep
    from torquemod.sweep.spec import MAX_POINTS, load_sweep
    check_cluster(args.scheduler, args.workers, args.connect_timeout)
    spec = load_sweep(args.sweep, max_points=None if args.yes else args.max_points or MAX_POINTS)
    say = _stage_printer(args)
    res = run_sweep(spec, Path(args.out), scheduler=args.scheduler, on_start=say and (
                        lambda: say(plan_line(spec, args.out, n_workers=args.workers,
                                              scheduler=args.scheduler))),
                    n_workers=args.workers, force=args.force, progress=not args.quiet,
                    connect_timeout_s=args.connect_timeout,
                    on_dashboard=lambda link: print(f"dashboard: {link}", file=sys.stderr,
                                                    flush=True))
    print(f"{res.status.shape[0]} points: {res.count('done')} run, {res.count('skipped')} "
          f"unchanged (skipped), {res.count('failed')} failed in {res.wall_s:.1f} s")
    for row in res.failures.itertuples():
        print(f"failed: point {row.point_index} {row.params}: {row.message}", file=sys.stderr)
    print(f"recommendation: {res.recommendation.get('reasoning', '')}")
    print(f"results: {res.out_dir}" + (f" (report: {res.report})" if res.report else ""))
    return 0


class _UsageError(TorquemodError):
    """A command line that cannot be carried out (exit code 2, like bad input)."""


class _Parser(argparse.ArgumentParser):
    """A command line that cannot be parsed: one line on stderr (what is wrong, where the
    help is) and exit code 2, like every other bad input."""

    def error(self, message: str):
        self.exit(EXIT_BAD_INPUT, f"{self.prog}: error: {' '.join(message.split())} (see "
                                  f"'{self.prog} --help')\n")


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="torquemod", description=(
        "Torque-modulation measurement of the wheel-rail coefficient of friction."))
    p.add_argument("--version", action="version", version=f"torquemod {__version__}")
    p.add_argument("--debug", action="store_true", help="show tracebacks of internal errors")
    # --debug is accepted after the subcommand too (the error hint suggests it there)
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("--debug", action="store_true", default=argparse.SUPPRESS,
                        help="show tracebacks of internal errors")
    sub = p.add_subparsers(dest="command", required=True)

    q = sub.add_parser("process", parents=[common],
                       help="run the processing chain on an experiment")
    q.add_argument("experiment", help="experiment.toml (or its folder)")
    q.add_argument("--out", required=True, help="results folder to create")
    q.add_argument("--phase-method", choices=["paper", "sinefit"], default=None,
                   help="phase estimator (default: paper)")
    q.add_argument("--nan-policy", choices=["raise", "interpolate", "drop-cycle"],
                   default=None, help="what to do with NaN/inf samples (default: raise)")
    q.add_argument("--force", action="store_true", help="replace an existing results folder")
    q.add_argument("--no-fit", action="store_true", help="skip the fit and report stages")
    q.add_argument("--quiet", action="store_true", help="no progress bar or stage lines")
    _add_pdf_options(q)
    q.add_argument("--export", default="", metavar="FORMATS",
                   help="also write cycles and steps as mat (MATLAB) and/or parquet, "
                        "comma-separated, beside cycles.csv and steps.csv")
    q.set_defaults(func=cmd_process)

    s = sub.add_parser("simulate", parents=[common],
                       help="simulate the V-Track experiment (digital twin)")
    s.add_argument("config", nargs="?", default=None, help="simulation config TOML")
    s.add_argument("--out", default=None, help="experiment folder to create")
    s.add_argument("--seed", type=int, default=0,
                   help="seed of the simulated noise and disturbances (default 0); the same "
                        "seed gives the same files")
    s.add_argument("--format", choices=["csv", "hdf5"], default="csv",
                   help="file format of the rig recordings (default csv; hdf5 is smaller and "
                        "faster to read)")
    s.add_argument("--print-config", action="store_true", help="print the default config")
    s.add_argument("--train", action="store_true",
                   help="simulate a train run (powered wheelset, friction map) instead of "
                        "the rig; also chosen by kind = \"train\" in the config")
    s.add_argument("--force", action="store_true",
                   help="replace an existing folder (one torquemod wrote)")
    s.add_argument("--quiet", action="store_true", help="no progress bar or stage lines")
    s.set_defaults(func=cmd_simulate)

    o = sub.add_parser("onboard", parents=[common],
                       help="the friction along a train run (run.toml) from torque and speed")
    o.add_argument("run", help="run.toml (or its folder)")
    o.add_argument("--out", required=True, help="results folder to create")
    o.add_argument("--force", action="store_true", help="replace an existing results folder")
    o.add_argument("--quiet", action="store_true", help="no stage lines")
    o.add_argument("--export", default="", metavar="FORMATS",
                   help="also write the tracks as csv and/or mat (MATLAB), comma-separated, "
                        "beside track.parquet")
    _add_pdf_options(o)
    o.set_defaults(func=cmd_onboard)

    f = sub.add_parser("fit", parents=[common], help=(
        "(re)fit the creep curve of a results folder and update it (fit.json, steps.csv, "
        "figures, report.html)"))
    f.add_argument("results", help="results folder written by 'torquemod process'")
    f.add_argument("--velocity-dependent", action="store_true",
                   help="fit Polach's falling friction (Eq. 9; needs differing speeds)")
    f.add_argument("--unweighted", action="store_true",
                   help="ignore the steps' standard errors in the force fit")
    f.add_argument("--stiffness", type=float, default=None,
                   help="contact stiffness s = pi*G*a*b*c11/(4*Q) [-] to report kA, kS alone")
    f.add_argument("--inertia", type=float, default=None, metavar="J_KG_M2",
                   help="wheel-side inertia [kg*m^2] for the theory constant C")
    f.add_argument("--theory-constant", type=float, default=None, metavar="C",
                   help="use this theory constant C [-] instead of the rig's")
    f.add_argument("--onset-criterion", default=None,
                   choices=["tan_ratio", "phase", "creep_coefficient", "either", "both"],
                   help="saturation-onset rule (default: tan_ratio)")
    f.add_argument("--seed", type=int, default=None, help="seed of the fit's random starts")
    f.add_argument("--quiet", action="store_true", help="no stage lines")
    _add_pdf_options(f)
    f.set_defaults(func=cmd_fit)

    r = sub.add_parser("report", parents=[common],
                       help="(re)draw the figures and report.html of a results folder")
    r.add_argument("results", help="results folder written by 'torquemod process'")
    r.add_argument("--step", type=int, default=None,
                   help="step shown in Figure 1, the signals (default 3)")
    r.add_argument("--cycle", type=int, default=None, help="cycle shown in Figure 1 (default 1)")
    r.add_argument("--title", default=None, help="page title (default: experiment name)")
    r.add_argument("--quiet", action="store_true", help="no stage lines")
    _add_pdf_options(r)
    r.set_defaults(func=cmd_report)

    d = sub.add_parser("demo", parents=[common],
                       help="simulate, process, fit and report the V-Track default")
    d.add_argument("--out", default="demo-output",
                   help="folder to create with the experiment, results and reports (default "
                        "demo-output)")
    d.add_argument("--config", default=None,
                   help="simulation config TOML (default: the V-Track experiment; see "
                        "'torquemod simulate --print-config')")
    d.add_argument("--seed", type=int, default=0,
                   help="seed of the simulated noise (default 0)")
    d.add_argument("--quick", action="store_true",
                   help="a shortened experiment (2 cycles per step): faster, less precise")
    d.add_argument("--no-train", action="store_true",
                   help="only the rig (skip the train run and its on-board estimate)")
    d.add_argument("--force", action="store_true",
                   help="replace an existing --out folder (one torquemod wrote)")
    d.add_argument("--quiet", action="store_true", help="no progress bars or stage lines")
    d.set_defaults(func=cmd_demo)

    c = sub.add_parser("convert", parents=[common],
                       help="write a recording as HDF5, Parquet, .mat or CSV (an "
                            "experiment as HDF5)", epilog=(
                           "examples: 'torquemod convert run1.tdms --out run1.h5' (or "
                           "run1.parquet, run1.mat, run1.csv: the suffix chooses); "
                           "'torquemod convert logger.mat --manifest experiment.toml --out "
                           "logger.h5' (read with the manifest's [channels]); 'torquemod "
                           "convert --manifest experiment.toml --out converted/' (every "
                           "recording plus a new experiment.toml)"))
    c.add_argument("input", nargs="?", help="recording file (any supported format)")
    c.add_argument("--manifest", default=None, help=(
        "experiment.toml: with INPUT, read INPUT with its [channels] table (and its entry's "
        "group and sample rate); without INPUT, convert the whole experiment into the folder "
        "--out"))
    c.add_argument("--out", required=True,
                   help="output .h5, .parquet, .mat or .csv file (or folder, for a whole "
                        "experiment)")
    c.add_argument("--force", action="store_true", help=(
        "replace an existing output (a folder only if torquemod wrote it; never an input)"))
    c.set_defaults(func=cmd_convert)

    fl = sub.add_parser("fleet", parents=[common],
                        help="process many experiments and train runs in parallel on Dask",
                        epilog=(
                            "examples: 'torquemod fleet runs/ --out fleet/' (every "
                            "experiment.toml and run.toml below runs/); 'torquemod fleet "
                            "runs.txt --out fleet/ --scheduler tcp://host:8786' (a list "
                            "file, an existing Dask cluster)"))
    fl.add_argument("runs", nargs="+", help="manifests, folders holding them, globs or list "
                    "files (one path per line)")
    fl.add_argument("--out", required=True, help="fleet results folder (Parquet datasets, "
                    "fleet_summary.csv, failures.csv, fleet_report.html)")
    fl.add_argument("--scheduler", default=None, metavar="ADDRESS",
                    help="address of an existing Dask scheduler (default: a local cluster "
                    "sized to the machine)")
    fl.add_argument("--workers", type=int, default=None, metavar="N",
                    help="worker processes of the local cluster (default: CPU count)")
    fl.add_argument("--connect-timeout", type=_positive_seconds, default=CONNECT_TIMEOUT_S,
                    metavar="S", help="seconds to wait for --scheduler to answer (default "
                    f"{CONNECT_TIMEOUT_S:g})")
    fl.add_argument("--force", action="store_true", help="reprocess unchanged runs too")
    fl.add_argument("--quiet", action="store_true", help="no progress bar")
    fl.add_argument("--revolutions-per-task", type=_positive_int, default=None, metavar="N",
                    help="split a rig recording with random row access (HDF5, MAT v7.3, "
                    "TDMS, MDF4) into one task per N revolutions (default: only files of "
                    ">= 256 MiB, ~60 s of recording a task); same numbers as one task")
    fl.set_defaults(func=cmd_fleet)

    sw = sub.add_parser("sweep", parents=[common],
                        help="sensitivity study: the twin over a grid of parameters, on Dask",
                        epilog="example: 'torquemod sweep examples/sweep_vtrack_conditions."
                               "toml --out out/sweep' (format: docs/sweep.md)")
    sw.add_argument("sweep", help="sweep file (SWEEP.toml)")
    sw.add_argument("--out", required=True, help="sweep results folder (sweep.parquet, "
                    "failures.csv, sweep.json, figures, report.html); rerun to resume")
    sw.add_argument("--scheduler", default=None, metavar="ADDRESS",
                    help="address of an existing Dask scheduler (default: a local cluster "
                    "sized to the machine)")
    sw.add_argument("--workers", type=int, default=None, metavar="N",
                    help="worker processes of the local cluster (default: CPU count)")
    sw.add_argument("--connect-timeout", type=_positive_seconds, default=CONNECT_TIMEOUT_S,
                    metavar="S", help="seconds to wait for --scheduler to answer (default "
                    f"{CONNECT_TIMEOUT_S:g})")
    sw.add_argument("--force", action="store_true", help="rerun finished points too; start "
                    "a new study in an --out that holds another sweep's points")
    sw.add_argument("--max-points", type=_positive_int, default=None, metavar="N",
                    help="refuse a sweep of more than N points (default: "
                    f"{_MAX_POINTS})")
    sw.add_argument("--yes", action="store_true", help="run a sweep of any size")
    sw.add_argument("--quiet", action="store_true", help="no progress bar")
    sw.set_defaults(func=cmd_sweep)
    return p


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    if "_ARGCOMPLETE" in os.environ:  # the shell asks for completions; exits when done
        import argcomplete
        argcomplete.autocomplete(parser)
    args = parser.parse_args(argv)
    try:
        with _terminate_as_interrupt():
            return int(args.func(args) or 0)
    except TorquemodError as exc:
        print(f"torquemod: error: {_one_line(exc)}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except BrokenPipeError:  # the reader of stdout went away (`| head`): nothing to say
        with contextlib.suppress(OSError):
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return EXIT_BROKEN_PIPE
    except KeyboardInterrupt as exc:  # Ctrl-C: 128 + SIGINT; kill: 128 + SIGTERM
        if isinstance(exc, _Terminated) or _TERMINATED.is_set():
            print("torquemod: terminated", file=sys.stderr)
            return EXIT_TERMINATED
        print("torquemod: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except Exception as exc:
        from torquemod._util.fsutil import environment_error
        env = environment_error(exc)  # full disk, read-only, no permission, ... (also deep
        if env is not None:           # inside numpy/pandas/h5py writes): the system's fault
            print(f"torquemod: error: {_os_error_line(env, args)}", file=sys.stderr)
            return EXIT_BAD_INPUT
        if args.debug:  # a bug: say so in one line unless asked for the traceback
            raise
        print(f"torquemod: internal error: {type(exc).__name__}: {_one_line(exc)} (rerun "
              "with --debug and report it)", file=sys.stderr)
        return EXIT_INTERNAL


_TERMINATED = threading.Event()


class _Terminated(KeyboardInterrupt):
    """SIGTERM, unwinding as Ctrl-C does (exit code 143 instead of 130)."""


@contextlib.contextmanager
def _terminate_as_interrupt():
    """SIGTERM (``kill``, a job scheduler's stop) unwinds like Ctrl-C, so temporary outputs
    are removed and nothing half-written is left (main thread only); the exit code is
    143."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def stop(_signum, _frame):
        _TERMINATED.set()  # also when a library turns the exception into a new one
        raise _Terminated

    _TERMINATED.clear()  # a SIGTERM of an earlier main() in this process is not this one's
    previous = signal.signal(signal.SIGTERM, stop)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def _one_line(exc: BaseException) -> str:
    """The message on one line, in the command line's words: the library's keyword
    ``force=True`` is the option ``--force`` here."""
    text = " ".join(str(exc).split())
    return text.replace("pass force=True", "use --force").replace("force=True", "--force")


def _os_error_line(exc: OSError, args: argparse.Namespace) -> str:
    """``path: reason`` for an OSError of the system: the file it names, else the command's
    output (``--out`` or the results folder)."""
    path = exc.filename or getattr(args, "out", None) or getattr(args, "results", None)
    reason = exc.strerror or _one_line(exc)
    return f"{path}: {reason}" if path else reason


if __name__ == "__main__":
    sys.exit(main())
