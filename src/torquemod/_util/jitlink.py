"""The memory that numba's compiler keeps once kernels are loaded from its on-disk cache.

A kernel compiled with ``cache=True`` is stored as its machine code plus the LLVM bitcode of
its module, kept so that a kernel compiled later can link it in and inline it. numba parses
that bitcode when the kernel is loaded and holds the parsed module for the rest of the
process, whether or not anything is ever linked against it. Parsed LLVM IR takes several
times the bitcode's size: for the 20 kernels `torquemod process` loads (6.5 MB of cache
files) it held ~59 MiB, more than the process's whole working set of one revolution.

:func:`lean_cached_kernels` changes what a kernel loaded from the cache keeps: the machine
code as before (what runs is untouched), the bitcode as bytes, and the parsed module only
while the load needs its symbol names. Should a kernel compiled later link one of them in,
its module is parsed again from the bytes at that moment, as numba does on loading. It
touches two private methods of ``numba.core.codegen.CPUCodeLibrary`` (``_unserialize``,
``_get_module_for_linking``); with a numba that lacks them it changes nothing.

:func:`release_compiler_pages` takes the pages of LLVM's own library that loading touched
out of the resident set (on Linux); the first load from the cache, which also compiles
numba's runtime, does it once the change above is in place.
"""

from __future__ import annotations

import functools
import threading

_INSTALLED: list[bool] = []
_LOCK = threading.RLock()
_LOADED: list[bool] = []

#: the attribute under which a library loaded from the cache keeps its linking bitcode
_BITCODE = "_torquemod_linking_bitcode"


def lean_cached_kernels() -> bool:
    """Have kernels loaded from numba's cache from now on drop their parsed linking module
    (the process-wide change described in the module docstring), and the first of them
    release LLVM's pages (:func:`release_compiler_pages`). Idempotent.

    Returns
    -------
    bool
        True if the change is in place, False if this numba's code library does not have
        the methods it wraps (nothing changed).
    """
    with _LOCK:
        if not _INSTALLED:
            _INSTALLED.append(_install())
    return _INSTALLED[0]


def _install() -> bool:
    """Wrap the two methods; False if they are not there."""
    try:
        from llvmlite import binding as ll
        from numba.core.codegen import CPUCodeLibrary
        unserialize = CPUCodeLibrary.__dict__["_unserialize"].__func__
        for_linking = CPUCodeLibrary.__dict__["_get_module_for_linking"]
    except (ImportError, KeyError, AttributeError):
        return False

    @functools.wraps(unserialize)
    def _unserialize(cls, codegen, state):
        lib = unserialize(cls, codegen, state)
        try:  # a state of another shape (another numba) keeps numba's own behaviour
            _name, kind, data = state
            bitcode = data[1] if kind == "object" else None
        except (TypeError, ValueError, IndexError):
            bitcode = None
        if isinstance(bitcode, bytes) and getattr(lib, "_shared_module", None) is not None:
            setattr(lib, _BITCODE, bitcode)
            lib._shared_module = None  # parsed again if a later kernel links this one in
        if not _LOADED:  # the first load also compiled numba's runtime: LLVM's optimiser
            _LOADED.append(True)
            release_compiler_pages()
        return lib

    @functools.wraps(for_linking)
    def _get_module_for_linking(self):
        bitcode = self.__dict__.get(_BITCODE)
        if bitcode is not None and self._shared_module is None:
            self._shared_module = ll.parse_bitcode(bitcode)
        return for_linking(self)

    CPUCodeLibrary._unserialize = classmethod(_unserialize)
    CPUCodeLibrary._get_module_for_linking = _get_module_for_linking
    return True


#: madvise(2) advice: drop the pages from this process's page tables
_MADV_DONTNEED = 4
#: (start, stop) of LLVM's clean read-only mappings, found once (a library stays mapped)
_LLVM_RANGES: list[tuple[int, int]] = []


def _clean_file_mappings(match) -> list[tuple[int, int]]:
    """(start, stop) of every private, read-only mapping of a file whose path ``match``
    accepts and of which no page differs from the file (``Anonymous: 0 kB`` in
    ``/proc/self/smaps``)."""
    out, cur = [], None
    with open("/proc/self/smaps") as fh:
        for line in fh:
            head = line.split(None, 5)
            if not head:
                continue
            if "-" in head[0] and not head[0].endswith(":"):
                start, stop = (int(x, 16) for x in head[0].split("-"))
                perm = head[1]
                path = head[5].strip() if len(head) > 5 else ""
                cur = ((start, stop) if path.startswith("/") and match(path)
                       and "w" not in perm and perm.endswith("p") else None)
            elif cur is not None and head[0] == "Anonymous:":
                if int(head[1]) == 0:
                    out.append(cur)
                cur = None
    return out


def release_compiler_pages() -> int:
    """Take the pages of LLVM's code (llvmlite's shared library) that this process has read
    out of its resident set.

    Loading kernels from numba's cache runs LLVM (parsing, linking the machine code, and
    numba's runtime, compiled once per process) and touches ~65 MiB of its 170 MiB library;
    the kernels then run without it. The pages released are the file's own, never written:
    only private read-only mappings without a page of their own (``Anonymous: 0 kB``; a
    read-only mapping cannot gain one later) are released, so this is what the kernel does
    to clean file pages under memory pressure. They stay in the page cache, and a page used
    again is mapped back from it on first access, so releasing is safe at any moment, only
    useless while LLVM is still busy.

    Returns
    -------
    int
        Bytes of mappings released (0 off Linux or before llvmlite's library is loaded).
    """
    import os
    import sys
    if not sys.platform.startswith("linux"):
        return 0
    try:
        import ctypes
        madvise = ctypes.CDLL(None, use_errno=True).madvise
        madvise.argtypes = [ctypes.c_void_p, ctypes.c_size_t, ctypes.c_int]
        with _LOCK:
            if not _LLVM_RANGES:
                _LLVM_RANGES.extend(_clean_file_mappings(
                    lambda p: os.path.basename(p).startswith("libllvmlite")))
    except (OSError, AttributeError, ValueError, IndexError):
        return 0
    done = 0
    for start, stop in _LLVM_RANGES:
        if madvise(start, stop - start, _MADV_DONTNEED) == 0:
            done += stop - start
    return done
