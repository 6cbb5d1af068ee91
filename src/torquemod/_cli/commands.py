"""The commands: each ``cmd_*`` takes the parsed arguments, calls the library and prints."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from torquemod._cli.exits import UsageError
from torquemod._cli.output import (
    fmt,
    print_fit,
    print_steps,
    print_stretches,
    print_train_demo,
    print_warnings,
    stage_printer,
    why_they_differ,
)


def cmd_process(args: argparse.Namespace) -> int:
    from torquemod.api import run

    out = run(args.experiment, args.out, phase_method=args.phase_method,
              nan_policy=args.nan_policy, fit=not args.no_fit, force=args.force,
              report_options=pdf_option(args),
              progress=not args.quiet, command=sys.argv, on_stage=stage_printer(args),
              export=args.export)
    res, ana = out.result, out.analysis
    print_warnings(res.warnings + (ana.warnings if ana is not None else []))
    print_steps(ana.steps if ana is not None else res.steps)
    if ana is not None:
        print_fit(ana)
    t = out.stage_s
    print(f"done in {t['total']:.1f} s: processing {len(res.cycles)} cycles "
          f"{t['process']:.1f} s ({res.timing_s['workers']} threads), fit {t['fit']:.1f} s, "
          f"writing results{' and report' if ana is not None else ''} {t['write']:.1f} s")
    print(f"results: {out.folder}")
    if out.report is not None:
        print(f"report:  {out.report}")
        print_pdf(args, out.report)
    return 0


def train_config(args: argparse.Namespace):
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
    say = stage_printer(args)
    if say:
        say("simulating the train run (the first run compiles the twin's numba kernels) ...")
    from torquemod.errors import InputError, ProcessingError
    try:
        summary = run_train_simulation(config, Path(args.out), seed=args.seed,
                                       force=args.force)
    except ProcessingError as exc:  # the twin could not run this configuration: name it
        raise InputError(str(exc), path=args.config or "the default train config") from None
    if summary["recording"] == "run.mf4":
        print(f"train run written to {args.out}/run.toml (MDF4) and run_h5.toml (HDF5), truth "
              "in truth.parquet")
    else:
        print(f"train run written to {args.out}/run.toml (HDF5; no MDF4 copy: install "
              "torquemod[mdf] for it), truth in truth.parquet")
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
    say = stage_printer(args)
    run = api.read_run(args.run)
    check_onboard_out(run, args.out, force=args.force)  # an occupied --out: before the work
    if say:
        say("estimating the friction along the run ...")
    results = [api.onboard(run, axle=e.axle) for e in run.recordings]
    save_onboard(results, Path(args.out), force=args.force, command=sys.argv, export=export)
    print_warnings([w for r in results for w in r.warnings])
    for r in results:
        s = r.summary()
        print(f"axle {s['axle']}: {s['windows']} windows over {s['length_m']:.0f} m, mu "
              f"determined in {100 * s['mu_given_share']:.0f} % (elsewhere a lower bound), "
              f"measurable in {100 * s['measurable_share']:.0f} %, "
              f"low adhesion {100 * s['low_adhesion_share']:.1f} %, slip "
              f"{100 * s['slip_share']:.1f} %; {s['seconds']:.1f} s")
        print_stretches(r.along_track())
    print(f"track:  {Path(args.out) / 'track.parquet'}"
          + (f" (also as {', '.join('track.' + f for f in export)})" if export else ""))
    print(f"along the track: {Path(args.out) / 'along_track.csv'} (per segment), "
          "along_track_km.csv (per km)")
    print(f"report: {Path(args.out) / 'report.html'}")
    write_pdf(args, Path(args.out) / "report.html")
    return 0


def check_seed(seed: int) -> None:
    if seed < 0:
        raise UsageError(f"--seed must be 0 or more, got {seed}")


def cmd_simulate(args: argparse.Namespace) -> int:
    if args.print_config and args.train:
        from torquemod.twins.train import default_train_config_text
        sys.stdout.write(default_train_config_text())
        return 0
    if args.print_config:
        from torquemod.twins.vtrack.simconfig import default_config_text
        sys.stdout.write(default_config_text())
        return 0
    if args.out is None:
        raise UsageError("simulate needs --out DIR (or --print-config)")
    check_seed(args.seed)
    train = train_config(args)
    if train is not None:
        return cmd_simulate_train(args, train)
    from torquemod.twins.vtrack.simconfig import load_config
    config = load_config(args.config)  # a bad config is one line, before any stage
    say = stage_printer(args)
    if say:
        say(COMPILE_NOTE)
    from torquemod.twins.vtrack import simulate  # the simulator's stage has begun
    truth = simulate.run_simulation(config, Path(args.out), seed=args.seed, fmt=args.format,
                                    progress=not args.quiet, force=args.force)
    print(f"experiment written to {args.out}/experiment.toml")
    for st in truth.get("steps", []):
        flag = "  SLIP" if st.get("slipped") else ""
        print(f"  step {st['step']}: DC {st['dc_torque_nm']:.2f} N*m, creepage "
              f"{fmt(st.get('creepage'), '.3e')}, CoA {fmt(st.get('coa'), '.4f')}, theory "
              f"phase {fmt(st.get('phase_theory_deg'), '.2f')} deg{flag}")
    return 0


MAX_POINTS = 2000  # torquemod.sweep.spec.MAX_POINTS (not imported for --help's sake)


COMPILE_NOTE = ("simulating the experiment (the first run compiles the simulator's numba "
                 "kernels, which can take a minute; later runs reuse the compiled cache) ...")


def fit_options(args: argparse.Namespace) -> dict:
    """The ``fit`` subcommand's options as FitOptions fields (only those given)."""
    opts = {"velocity_dependent": args.velocity_dependent or None,
            "weighted": False if args.unweighted else None,
            "stiffness": args.stiffness, "inertia_kg_m2": args.inertia,
            "theory_constant": args.theory_constant, "onset_criterion": args.onset_criterion,
            "seed": args.seed}
    return {k: v for k, v in opts.items() if v is not None}


def cmd_fit(args: argparse.Namespace) -> int:
    from torquemod.api import fit_folder
    _, ana = fit_folder(Path(args.results), fit_options(args),
                        report_options=pdf_option(args), on_stage=stage_printer(args))
    print_warnings(ana.warnings)
    print_steps(ana.steps)
    print_fit(ana)
    print(f"updated {args.results}: fit.json, steps.csv, figures and report.html"
          + (" (and report.pdf)" if args.pdf else ""))
    return 0


def cmd_report(args: argparse.Namespace) -> int:
    from torquemod.api import report_folder
    opts = {k: v for k, v in (("step", args.step), ("cycle", args.cycle),
                              ("title", args.title)) if v is not None} | pdf_option(args)
    path = report_folder(Path(args.results), report_options=opts,
                         on_stage=stage_printer(args))
    print(f"report written to {path}")
    print_pdf(args, path)
    return 0


def pdf_option(args: argparse.Namespace) -> dict:
    """--pdf as the report option that writes report.pdf inside the results folder."""
    return {"pdf": args.pdf_engine} if getattr(args, "pdf", False) else {}


def print_pdf(args: argparse.Namespace, html_path: Path) -> None:
    if getattr(args, "pdf", False):
        print(f"pdf:     {Path(html_path).with_suffix('.pdf')}")


def write_pdf(args: argparse.Namespace, html_path: Path) -> None:
    """With --pdf: the report as report.pdf beside it (A4; see torquemod.report.pdf)."""
    if not getattr(args, "pdf", False):
        return
    from torquemod.report.pdf import html_to_pdf
    say = stage_printer(args)
    if say:
        say(f"writing the PDF ({args.pdf_engine}) ...")
    print(f"pdf:    {html_to_pdf(html_path, engine=args.pdf_engine)}")


def cmd_demo(args: argparse.Namespace) -> int:
    from torquemod.demo import run_demo
    check_seed(args.seed)
    say = stage_printer(args)
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
              f"{fmt(st.get('torque_pct_saturation'), '8.1f')} "
              f"{fmt(st.get('phase_deg'), '12.2f')} {fmt(st.get('phase_theory_deg'), '13.2f')}")
    print()
    print_warnings(out["analysis"].warnings)
    print_fit(out["analysis"])
    truth = out.get("truth") or {}
    if truth.get("peak_coa") is not None:
        print(f"simulator truth: mu0 = {truth['mu0']:.4f}, falling with slip velocity to "
              f"{truth['mu_at_top_step']:.4f} at the top step (Polach Eq. 9); creep-curve "
              f"peak CoA {truth['peak_coa']:.4f} at {fmt(truth.get('peak_torque_nm'), '.2f')} "
              f"N*m; slip at step {truth.get('slip_step')}")
        print(why_they_differ(out, truth))
    if out.get("train"):
        print_train_demo(out["train"])
    return 0


def cmd_convert(args: argparse.Namespace) -> int:
    from torquemod.io import convert
    if args.input is None and not args.manifest:
        raise UsageError("convert needs an INPUT recording or --manifest EXPERIMENT.toml")
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


#: torquemod.sweep.run.WORKER_MODULES (not imported: the fork server starts before the imports)
SWEEP_WORKER_MODULES = ("torquemod.sweep.workerpreload",)


def cmd_sweep(args: argparse.Namespace) -> int:
    from torquemod._util.daskutil import (
        EarlyCluster,
        check_cluster,
        forking_available,
        start_worker_server,
    )
    out = Path(args.out)
    fresh = not out.exists() or (out.is_dir() and not any(out.iterdir()))
    local = check_cluster(args.scheduler, args.workers, args.connect_timeout) is None
    if local and fresh:
        # a new output folder: every point runs, on a local cluster whose workers fork from
        # a server that imports what they need meanwhile, on another core while this
        # process imports and reads the sweep (in a folder with finished points the
        # cluster, if any is needed, starts the server itself)
        start_worker_server(SWEEP_WORKER_MODULES)
    from torquemod.sweep.run import plan_line, run_sweep
    from torquemod.sweep.spec import MAX_POINTS, load_sweep
    spec = load_sweep(args.sweep, max_points=None if args.yes else args.max_points or MAX_POINTS)
    # the sweep file is sound: the cluster starts in a thread while the output folder and
    # the points are checked (and waits for the server's imports there, not here)
    early = (EarlyCluster(args.workers, SWEEP_WORKER_MODULES)
             if local and fresh and forking_available() else None)
    try:
        say = stage_printer(args)
        res = run_sweep(spec, Path(args.out), scheduler=args.scheduler, on_start=say and (
                            lambda: say(plan_line(spec, args.out, n_workers=args.workers,
                                                  scheduler=args.scheduler))),
                        n_workers=args.workers, force=args.force, progress=not args.quiet,
                        connect_timeout_s=args.connect_timeout, cluster=early,
                        on_dashboard=lambda link: print(f"dashboard: {link}",
                                                        file=sys.stderr, flush=True))
    finally:
        if early is not None:  # not used after all (a refused output folder): closed here
            early.close()
    print(f"{res.status.shape[0]} points: {res.count('done')} run, {res.count('skipped')} "
          f"unchanged (skipped), {res.count('failed')} failed in {res.wall_s:.1f} s")
    for row in res.failures.itertuples():
        print(f"failed: point {row.point_index} {row.params}: {row.message}", file=sys.stderr)
    print(f"recommendation: {res.recommendation.get('reasoning', '')}")
    print(f"results: {res.out_dir}" + (f" (report: {res.report})" if res.report else ""))
    return 0
