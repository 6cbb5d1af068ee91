"""The ``torquemod`` command line. The only module that parses arguments or prints.

Every :class:`~torquemod.errors.TorquemodError` ends as one line on stderr and exit code 2;
anything else is a bug: one line, exit code 3, and ``--debug`` shows the traceback.
"""

from __future__ import annotations

import argparse
import math
import sys
import warnings
from pathlib import Path

from ._version import __version__
from .errors import TorquemodError, TorquemodWarning

EXIT_BAD_INPUT = 2
EXIT_INTERNAL = 3


def _fmt(x: object, spec: str) -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "-"
    return format(x, spec)


def _print_steps(steps) -> None:
    print(f"{'step':>4} {'DC [N*m]':>9} {'phase [deg]':>12} {'std':>6} {'creepage':>10} "
          f"{'CoA':>7} {'cycles':>6}")
    for r in steps.itertuples():
        print(f"{r.step:>4} {r.dc_torque_nm:>9.2f} {_fmt(r.phase_deg, '12.3f')} "
              f"{_fmt(r.phase_std_deg, '6.3f')} {_fmt(r.creepage, '10.3e')} "
              f"{_fmt(r.coa, '7.4f')} {r.n_cycles:>6}"
              + ("  SLIP (not fitted)" if getattr(r, "slip", False) else ""))


def _post_stages(args: argparse.Namespace, summary: dict):
    """The fit and report stages run on a results folder (before it is published); the
    fit's summary is stored into ``summary``."""
    if getattr(args, "no_fit", False):
        return None

    def post(folder: Path) -> None:
        from .analysis import fit_results_folder
        from .report import write_report
        summary.update(fit_results_folder(folder))
        write_report(folder)
    return post


def _print_fit(summary: dict) -> None:
    if not summary:
        return
    if summary.get("fit_skipped"):
        print(f"warning: Polach fit skipped: {summary['fit_skipped']}", file=sys.stderr)
    elif summary.get("mu_determined"):
        print(f"Polach fit: mu = {summary['mu']:.4f} +- {summary['mu_stderr']:.4f}, "
              f"saturation torque Ts = {summary['saturation_torque_nm']:.2f} N*m")
    else:
        print(f"Polach fit: mu not determined by these points; mu >= "
              f"{_fmt(summary.get('mu_lower_bound'), '.4f')}")
    lo, hi = summary.get("mu_from_phase_interval_95") or (None, None)
    if summary.get("mu_from_phase_determined"):
        print(f"mu from the phase: {summary['mu_from_phase']:.4f} "
              f"(95 % interval {_fmt(lo, '.4f')} .. {_fmt(hi, '.4f')})")
    elif lo is not None:
        print(f"mu from the phase: not determined by these steps; mu >= {lo:.4f}")
    onset = summary.get("onset_step")
    print(f"saturation onset: {'step ' + str(onset) if onset is not None else 'not reached'}; "
          f"theory vs measured phase: RMS {_fmt(summary.get('theory_rms_deg'), '.2f')} deg")


def cmd_process(args: argparse.Namespace) -> int:
    from .config import ProcessingConfig
    from .fsutil import check_output_dir
    from .io import read_experiment
    from .pipeline import process_experiment, write_results

    check_output_dir(args.out, force=args.force)
    exp = read_experiment(args.experiment)
    base = ProcessingConfig()
    proc_table = exp.extra.get("processing")
    if proc_table:
        base = ProcessingConfig.from_dict(proc_table, source=str(exp.manifest_path))
    cfg = base.with_phase_method(args.phase_method)
    if args.nan_policy:
        import dataclasses
        cfg = dataclasses.replace(cfg, nan_policy=args.nan_policy)
    result = process_experiment(exp, config=cfg, progress=not args.quiet)
    fit_summary: dict = {}
    write_results(result, args.out, force=args.force, command=sys.argv,
                  post=_post_stages(args, fit_summary))
    for w in result.warnings:
        print(f"warning: {w}", file=sys.stderr)
    _print_steps(result.steps)
    _print_fit(fit_summary)
    t = result.timing_s
    print(f"results in {args.out} ({len(result.cycles)} cycles in {t['wall_s']:.2f} s with "
          f"{t['workers']} threads: read {t['read_thread_s']:.2f} s, compute "
          f"{t['compute_thread_s']:.2f} s, summed over threads)")
    return 0


def cmd_simulate(args: argparse.Namespace) -> int:
    from . import simulate
    if args.print_config:
        sys.stdout.write(simulate.default_config_text())
        return 0
    if args.out is None:
        raise _UsageError("simulate needs --out DIR (or --print-config)")
    config = simulate.load_config(args.config)
    truth = simulate.run_simulation(config, Path(args.out), seed=args.seed, fmt=args.format,
                                    progress=not args.quiet, force=args.force)
    print(f"experiment written to {args.out}/experiment.toml")
    for st in truth.get("steps", []):
        flag = "  SLIP" if st.get("slipped") else ""
        print(f"  step {st['step']}: DC {st['dc_torque_nm']:.2f} N*m, creepage "
              f"{_fmt(st.get('creepage'), '.3e')}, CoA {_fmt(st.get('coa'), '.4f')}, theory "
              f"phase {_fmt(st.get('phase_theory_deg'), '.2f')} deg{flag}")
    return 0


def cmd_fit(args: argparse.Namespace) -> int:
    from .analysis import fit_results_folder
    summary = fit_results_folder(Path(args.results))
    for w in summary.get("warnings") or []:
        print(f"warning: {w}", file=sys.stderr)
    _print_fit(summary)
    print(f"fit written to {summary['fit_json']} (steps.csv updated; run 'torquemod report "
          f"{args.results}' to redraw the report)")
    return 0


def cmd_report(args: argparse.Namespace) -> int:
    from .report import write_report
    path = write_report(Path(args.results))
    print(f"report written to {path}")
    return 0


def cmd_demo(args: argparse.Namespace) -> int:
    from .demo import run_demo
    out = run_demo(Path(args.out), config_path=args.config, seed=args.seed, force=args.force,
                   progress=not args.quiet, quick=args.quick)
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
    _print_fit(out)
    truth = out.get("truth") or {}
    if truth.get("peak_coa") is not None:
        print(f"simulator truth: mu0 = {truth['mu0']:.4f}, falling with slip velocity to "
              f"{truth['mu_at_top_step']:.4f} at the top step (Polach Eq. 9); creep-curve "
              f"peak CoA {truth['peak_coa']:.4f} at {_fmt(truth.get('peak_torque_nm'), '.2f')} "
              f"N*m; slip at step {truth.get('slip_step')}")
    return 0


def cmd_convert(args: argparse.Namespace) -> int:
    from . import convert
    if args.manifest:
        path = convert.convert_experiment(Path(args.manifest), Path(args.out))
    elif args.input is None:
        raise _UsageError("convert needs an INPUT recording or --manifest EXPERIMENT.toml")
    else:
        path = convert.convert_file(Path(args.input), Path(args.out))
    print(f"written {path}")
    return 0


class _UsageError(TorquemodError):
    """A command line that cannot be carried out (exit code 2, like bad input)."""


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="torquemod", description=(
        "Torque-modulation measurement of the wheel-rail coefficient of friction."))
    p.add_argument("--version", action="version", version=f"torquemod {__version__}")
    p.add_argument("--debug", action="store_true", help="show tracebacks of internal errors")
    sub = p.add_subparsers(dest="command", required=True)

    q = sub.add_parser("process", help="run the processing chain on an experiment")
    q.add_argument("experiment", help="experiment.toml (or its folder)")
    q.add_argument("--out", required=True, help="results folder to create")
    q.add_argument("--phase-method", choices=["paper", "sinefit"], default=None,
                   help="phase estimator (default: paper)")
    q.add_argument("--nan-policy", choices=["raise", "interpolate", "drop-cycle"],
                   default=None, help="what to do with NaN/inf samples (default: raise)")
    q.add_argument("--force", action="store_true", help="replace an existing results folder")
    q.add_argument("--no-fit", action="store_true", help="skip the fit and report stages")
    q.add_argument("--quiet", action="store_true", help="no progress bar")
    q.set_defaults(func=cmd_process)

    s = sub.add_parser("simulate", help="simulate the V-Track experiment (digital twin)")
    s.add_argument("config", nargs="?", default=None, help="simulation config TOML")
    s.add_argument("--out", default=None, help="experiment folder to create")
    s.add_argument("--seed", type=int, default=0)
    s.add_argument("--format", choices=["csv", "hdf5"], default="csv")
    s.add_argument("--print-config", action="store_true", help="print the default config")
    s.add_argument("--force", action="store_true", help="replace an existing folder")
    s.add_argument("--quiet", action="store_true")
    s.set_defaults(func=cmd_simulate)

    f = sub.add_parser("fit", help="(re)fit the creep curve of a results folder")
    f.add_argument("results")
    f.set_defaults(func=cmd_fit)

    r = sub.add_parser("report", help="(re)write figures and report.html of a results folder")
    r.add_argument("results")
    r.set_defaults(func=cmd_report)

    d = sub.add_parser("demo", help="simulate, process, fit and report the V-Track default")
    d.add_argument("--out", default="demo-output")
    d.add_argument("--config", default=None, help="simulation config TOML")
    d.add_argument("--seed", type=int, default=0)
    d.add_argument("--quick", action="store_true", help="a shortened experiment")
    d.add_argument("--force", action="store_true")
    d.add_argument("--quiet", action="store_true")
    d.set_defaults(func=cmd_demo)

    c = sub.add_parser("convert", help="write a recording (or experiment) as HDF5")
    c.add_argument("input", nargs="?", help="recording file")
    c.add_argument("--manifest", default=None, help="convert a whole experiment instead")
    c.add_argument("--out", required=True)
    c.set_defaults(func=cmd_convert)
    return p


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    warnings.simplefilter("ignore", TorquemodWarning)  # collected and printed by commands
    try:
        return int(args.func(args) or 0)
    except TorquemodError as exc:
        print(f"torquemod: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print("torquemod: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:  # a bug: say so in one line unless asked for the traceback
        if args.debug:
            raise
        print(f"torquemod: internal error: {type(exc).__name__}: {exc} (rerun with --debug "
              "and report it)", file=sys.stderr)
        return EXIT_INTERNAL


if __name__ == "__main__":
    sys.exit(main())
