"""Kernels loaded from numba's cache hold no parsed linking module
(torquemod._util.jitlink.lean_cached_kernels), and a kernel compiled later still links them
in: their module is parsed again from the kept bitcode when it is asked for. LLVM's pages
released from the resident set (release_compiler_pages) come back when LLVM runs again.

Each case runs in a fresh interpreter: the change is process-wide, and a kernel must come
from the cache, which a first interpreter fills."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap

import pytest

KERNELS = '''
import numba
import numpy as np

@numba.njit(cache=True)
def inner(x):
    return np.sum(x * x) + 1.0
'''

FILL = "import kernels, numpy as np; print(kernels.inner(np.arange(4.0)))"

USE = textwrap.dedent('''
    import json, sys
    import numba
    import numpy as np
    from torquemod._util.jitlink import lean_cached_kernels
    installed = lean_cached_kernels()
    import kernels
    x = np.arange(4.0)
    first = kernels.inner(x)
    (cres,) = kernels.inner.overloads.values()
    lib = cres.library
    from_cache = kernels.inner.stats.cache_hits
    held_after_load = lib._shared_module is not None

    @numba.njit
    def outer(y):  # compiled now: links the cached kernel's library in
        return 2.0 * kernels.inner(y)

    print(json.dumps({"installed": installed, "hits": sum(from_cache.values()),
                      "held_after_load": held_after_load, "first": first,
                      "outer": outer(x), "held_after_link": lib._shared_module is not None}))
''')


def test_cached_kernel_drops_its_module_and_still_links(tmp_path):
    (tmp_path / "kernels.py").write_text(KERNELS)
    head = f"import sys; sys.path.insert(0, {str(tmp_path)!r})\n"
    for code in (FILL, USE):  # the first fills the cache beside kernels.py
        run = subprocess.run([sys.executable, "-c", head + code], capture_output=True,
                             text=True)
        assert run.returncode == 0, run.stderr
    got = json.loads(run.stdout)
    assert got["installed"] is True
    assert got["hits"] == 1  # the kernel came from the cache, not the compiler
    assert got["held_after_load"] is False  # no parsed module held after the load
    assert got["first"] == 15.0  # 0 + 1 + 4 + 9, + 1
    assert got["outer"] == 30.0  # linked through the module parsed again from the bitcode
    assert got["held_after_link"] is True


RELEASE = textwrap.dedent('''
    import json, os
    import numba
    from torquemod._util.jitlink import release_compiler_pages

    def llvm_rss_kib():
        total, mine = 0, False
        with open("/proc/self/smaps") as fh:
            for line in fh:
                head = line.split()
                if "-" in head[0] and not head[0].endswith(":"):
                    mine = len(head) > 5 and os.path.basename(head[5]).startswith("libllvmlite")
                elif mine and head[0] == "Rss:":
                    total += int(head[1])
        return total

    @numba.njit
    def first(x):  # compiled here: LLVM's optimiser runs
        return x * 3.0 + 1.0

    assert first(2.0) == 7.0
    before = llvm_rss_kib()
    released = release_compiler_pages()
    after = llvm_rss_kib()

    @numba.njit
    def second(x):  # the pages come back from the page cache as LLVM runs again
        return first(x) - 1.0

    print(json.dumps({"before": before, "after": after, "released": released,
                      "second": second(2.0), "first": first(5.0)}))
''')


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="/proc and madvise: Linux")
def test_release_compiler_pages_leaves_llvm_working():
    run = subprocess.run([sys.executable, "-c", RELEASE], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    got = json.loads(run.stdout)
    assert got["released"] > 0
    assert got["before"] > 20_000  # KiB: compiling touched tens of MiB of LLVM's library
    assert got["after"] < got["before"] / 4  # read-only pages out of the resident set
    assert got["second"] == 6.0 and got["first"] == 16.0  # LLVM and the kernels still work
