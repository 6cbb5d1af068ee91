"""The argument parser of ``torquemod`` and its subcommands."""

from __future__ import annotations

import argparse
import math

from torquemod._cli.commands import (
    MAX_POINTS,
    cmd_convert,
    cmd_demo,
    cmd_fit,
    cmd_fleet,
    cmd_onboard,
    cmd_process,
    cmd_report,
    cmd_simulate,
    cmd_sweep,
)
from torquemod._cli.exits import EXIT_BAD_INPUT
from torquemod._util.daskutil import CONNECT_TIMEOUT_S
from torquemod._version import __version__


def positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a positive whole number, got {text!r}")
    return value


def positive_seconds(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not 0 < value < 1e6:
        raise argparse.ArgumentTypeError(f"expected a positive number of seconds, got {text!r}")
    return value


def add_pdf_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--pdf", action="store_true",
                        help="also write the report as report.pdf (A4) beside report.html")
    parser.add_argument("--pdf-engine", choices=["matplotlib", "chromium"],
                        default="matplotlib",
                        help="how the PDF is made: matplotlib (default, always available: "
                             "text, tables and figures laid out on A4) or chromium (a "
                             "headless Chromium on the PATH prints the HTML page)")


class Parser(argparse.ArgumentParser):
    """A command line that cannot be parsed: one line on stderr (what is wrong, where the
    help is) and exit code 2, like every other bad input."""

    def error(self, message: str):
        self.exit(EXIT_BAD_INPUT, f"{self.prog}: error: {' '.join(message.split())} (see "
                                  f"'{self.prog} --help')\n")


def build_parser() -> argparse.ArgumentParser:
    p = Parser(prog="torquemod", description=(
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
    add_pdf_options(q)
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
    add_pdf_options(o)
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
    add_pdf_options(f)
    f.set_defaults(func=cmd_fit)

    r = sub.add_parser("report", parents=[common],
                       help="(re)draw the figures and report.html of a results folder")
    r.add_argument("results", help="results folder written by 'torquemod process'")
    r.add_argument("--step", type=int, default=None,
                   help="step shown in Figure 1, the signals (default 3)")
    r.add_argument("--cycle", type=int, default=None, help="cycle shown in Figure 1 (default 1)")
    r.add_argument("--title", default=None, help="page title (default: experiment name)")
    r.add_argument("--quiet", action="store_true", help="no stage lines")
    add_pdf_options(r)
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
    fl.add_argument("--connect-timeout", type=positive_seconds, default=CONNECT_TIMEOUT_S,
                    metavar="S", help="seconds to wait for --scheduler to answer (default "
                    f"{CONNECT_TIMEOUT_S:g})")
    fl.add_argument("--force", action="store_true", help="reprocess unchanged runs too")
    fl.add_argument("--quiet", action="store_true", help="no progress bar")
    fl.add_argument("--revolutions-per-task", type=positive_int, default=None, metavar="N",
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
    sw.add_argument("--connect-timeout", type=positive_seconds, default=CONNECT_TIMEOUT_S,
                    metavar="S", help="seconds to wait for --scheduler to answer (default "
                    f"{CONNECT_TIMEOUT_S:g})")
    sw.add_argument("--force", action="store_true", help="rerun finished points too; start "
                    "a new study in an --out that holds another sweep's points")
    sw.add_argument("--max-points", type=positive_int, default=None, metavar="N",
                    help="refuse a sweep of more than N points (default: "
                    f"{MAX_POINTS})")
    sw.add_argument("--yes", action="store_true", help="run a sweep of any size")
    sw.add_argument("--quiet", action="store_true", help="no progress bar")
    sw.set_defaults(func=cmd_sweep)
    return p
