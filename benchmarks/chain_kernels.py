"""Each compiled kernel the chain calls from Python, timed alone on a cycle's own inputs
(prints figures, asserts nothing).

One cycle of ``throughput.py``'s benchmark (107 733 samples x 6 channels at 16 670 Hz,
resampled to 53.344 Hz) runs with every numba kernel of ``torquemod`` wrapped so that its
arguments are copied as it is called; each call is then repeated ``--repeats`` times, best
of five, in CPU time on one BLAS thread. A kernel's figure includes the kernels and library
routines it calls (BLAS, LAPACK, libm) but not Python's work around it, and its caches are
warm (the same inputs again): it isolates the compiled code's own changes from the glue and
from the machine's load better than ``chain_split.py`` does. The decimator's kernels are
left out (``throughput.py`` measures them).

    python benchmarks/chain_kernels.py [--repeats 100]
"""

from __future__ import annotations

import argparse
import collections
import sys
import time

import numpy as np

_SKIPPED = ("decimate.",)  # the decimation: measured by throughput.py


def _copy(x):
    """An argument as the kernel saw it: arrays copied with their write flag (a read-only
    array is another numba type), tuples element by element."""
    if isinstance(x, np.ndarray):
        c = x.copy(order="K")
        c.setflags(write=x.flags.writeable)
        return c
    if isinstance(x, tuple):
        return tuple(_copy(y) for y in x)
    return x


def _recording_wrappers(calls: list) -> list:
    """Every numba kernel bound in a ``torquemod`` module replaced by a wrapper that records
    its name and copied arguments in ``calls``; the (module, name, kernel) to undo it."""
    from numba.core.registry import CPUDispatcher

    wrappers: dict[int, object] = {}
    undo = []
    for name, module in list(sys.modules.items()):
        if not name.startswith("torquemod") or module is None:
            continue
        for attr, value in list(vars(module).items()):
            if not isinstance(value, CPUDispatcher):
                continue
            if id(value) not in wrappers:
                label = f"{value.py_func.__module__.rsplit('.', 1)[-1]}.{value.__name__}"

                def wrapper(*args, _fn=value, _label=label, **kwargs):
                    calls.append((_label, _fn, tuple(_copy(a) for a in args), kwargs))
                    return _fn(*args, **kwargs)

                wrappers[id(value)] = wrapper
            setattr(module, attr, wrappers[id(value)])
            undo.append((module, attr, value))
    return undo


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=100)
    args = ap.parse_args()
    from _cycle import benchmark_cycle

    from torquemod._util.blas import one_blas_thread

    _, _, _, run = benchmark_cycle()
    with one_blas_thread():
        run()  # compiled (or loaded) before the wrappers
        calls: list = []
        undo = _recording_wrappers(calls)
        try:
            run()
        finally:
            for module, attr, value in undo:
                setattr(module, attr, value)
        best = collections.defaultdict(float)
        count = collections.Counter()
        for label, fn, call_args, kwargs in calls:
            if label.startswith(_SKIPPED):
                continue
            inputs = [_copy(a) for a in call_args]
            fn(*inputs, **kwargs)
            fastest = float("inf")
            for _ in range(5):
                t0 = time.process_time()
                for _ in range(args.repeats):
                    fn(*inputs, **kwargs)
                fastest = min(fastest, (time.process_time() - t0) / args.repeats)
            best[label] += fastest
            count[label] += 1
    print(f"compiled kernels of one cycle, each alone on its inputs, best of 5 x "
          f"{args.repeats} calls, CPU time, one BLAS thread [us per cycle]:")
    for label, seconds in sorted(best.items(), key=lambda kv: -kv[1]):
        print(f"  {label:45s} {1e6 * seconds:8.1f}  ({count[label]} a cycle)")
    print(f"  {'total':45s} {1e6 * sum(best.values()):8.1f}")


if __name__ == "__main__":
    main()
