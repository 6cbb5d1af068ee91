"""Where a ``torquemod sweep`` command's time goes besides its points: a timeline.

Runs the command in this process (its arguments after ``--``) with its stages wrapped, and
prints, as each stage starts and ends, the wall time since the start and this process's
CPU (the command, the Dask scheduler and the nannies; not the workers): the sweep file,
the points' decision, the cluster's start (in a thread from the end of the sweep file on
when the output folder is new: "early"; joined when the points are submitted), the first
and last result, assembling the table, the recommendation, the Parquet, the report and
its figures (drawn on the workers when there is a local cluster); at the end the CPU of
the workers (children). Run on a finished folder, it times a rerun whose points are all
skipped.

    python benchmarks/sweep_phases.py -- examples/sweep_vtrack_conditions.toml --out OUT \
        --workers 2 --quiet
"""

from __future__ import annotations

import contextlib
import functools
import os
import resource
import sys
import threading
import time


def main(argv: list[str]) -> None:
    t0, c0 = time.perf_counter(), time.process_time()

    def stamp(label: str) -> None:
        print(f"{time.perf_counter() - t0:8.2f} s wall {time.process_time() - c0:7.2f} "
              f"CPU-s  {label}", file=sys.stderr, flush=True)

    import dask.distributed as dd

    import torquemod._util.daskutil as daskutil
    import torquemod.cli as cli
    import torquemod.sweep.report as report
    import torquemod.sweep.run as run
    import torquemod.sweep.spec as spec
    stamp("imports (the command, Dask, the report)")

    def wrap(mod, name: str) -> None:
        fn = getattr(mod, name)

        @functools.wraps(fn)
        def timed(*a, **k):
            stamp(f"> {name}")
            try:
                return fn(*a, **k)
            finally:
                stamp(f"< {name}")
        setattr(mod, name, timed)

    for mod, name in ((spec, "load_sweep"), (run, "load_sweep"), (run, "one_study"),
                      (run, "_unchanged"), (run, "assemble"), (run, "_write_parquet"),
                      (report, "recommend"), (report, "write_report")):
        if hasattr(mod, name):
            wrap(mod, name)
    client_of = daskutil.dask_client

    @contextlib.contextmanager
    def client(*a, **k):
        early = threading.current_thread().name == "torquemod-dask-start"
        what = ("cluster start (early, in a thread)" if early else
                "cluster joined (started early)" if k.get("started") is not None else
                "cluster start")
        stamp(f"> {what}")
        with client_of(*a, **k) as c:
            stamp(f"< {what}")
            yield c
            stamp("> cluster close (in a thread when the caller passes `closing`)")
        stamp("< cluster close")
    daskutil.dask_client = client
    try:
        import torquemod.sweep.finish as finish

        class TimedDrawer(finish.FigureDrawer):
            def submit(self, jobs):
                stamp(f"{len(jobs)} figures handed to the workers")
                return super().submit(jobs)

            def __call__(self, jobs):
                stamp(f"> {len(jobs)} figures drawn on the workers")
                try:
                    return super().__call__(jobs)
                finally:
                    stamp("< figures drawn on the workers")
        finish.draw_on = TimedDrawer
    except ImportError:  # an older checkout draws them in the command
        pass
    completed = dd.as_completed

    def results(futures):
        stamp(f"{len(futures)} tasks submitted")
        for k, fut in enumerate(completed(futures)):
            if k == 0:
                stamp("first result")
            yield fut
        stamp("last result")
    dd.as_completed = results
    with contextlib.suppress(SystemExit):
        cli.main(argv)
    stamp("end")
    # the workers forked from the fork server count once it is ended and waited for
    daskutil.stop_worker_server()
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    print(f"workers (children) CPU {children.ru_utime + children.ru_stime:.2f} s, load "
          f"{os.getloadavg()[0]:.2f}", file=sys.stderr)


if __name__ == "__main__":  # the workers import this file as their __mp_main__: no run there
    args = sys.argv[1:]
    main(["sweep", *args[args.index("--") + 1:]] if "--" in args else ["sweep", *args])
