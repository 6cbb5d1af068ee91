"""Compiled kernels loaded from numba's on-disk cache without their linking IR held in memory.

A kernel compiled with ``cache=True`` is stored as its machine code plus the LLVM bitcode of
its module, kept so that a kernel compiled later can link it in and inline it. numba parses
that bitcode when the kernel is loaded and holds the parsed module for the rest of the
process, whether or not anything is ever linked against it. Parsed LLVM IR takes several
times the bitcode's size: for the 20 kernels `torquemod process` loads (6.5 MB of cache
files) it held ~59 MiB, more than the process's whole working set of one revolution.

:func:`lean_cached_kernels` changes what a kernel loaded from the cache keeps: the machine
code as before (what runs is untouched), the bitcode as bytes, and the parsed module only
while the load needs its symbol names. Should a kernel compiled later link one of them in,
its module is parsed again from the bytes at that moment, as numba does on loading.

It touches two private methods of ``numba.core.codegen.CPUCodeLibrary``
(``_unserialize``, ``_get_module_for_linking``); with a numba that lacks them it changes
nothing.
"""

from __future__ import annotations

import functools
import threading

_INSTALLED: list[bool] = []
_LOCK = threading.Lock()

#: the attribute under which a library loaded from the cache keeps its linking bitcode
_BITCODE = "_torquemod_linking_bitcode"


def lean_cached_kernels() -> bool:
    """Have kernels loaded from numba's cache from now on drop their parsed linking module
    (the process-wide change described in the module docstring). Idempotent.

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
        _name, kind, data = state
        if kind == "object" and getattr(lib, "_shared_module", None) is not None:
            setattr(lib, _BITCODE, data[1])
            lib._shared_module = None  # parsed again if a later kernel links this one in
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
