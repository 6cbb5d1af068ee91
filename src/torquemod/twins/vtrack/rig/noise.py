"""Gaussian sensor noise drawn inside compiled kernels (numba): splitmix64 and a ziggurat.

:func:`add_normal` adds ``sd`` times standard normal numbers to a channel in one pass, the
channel's samples read from any strided source (a column of the integrator's output) and
written to a contiguous row. The generator is splitmix64 (Steele, Lea & Flood, "Fast
splittable pseudorandom number generators", OOPSLA 2014: a Weyl sequence of step
``0x9E3779B97F4A7C15`` through a 64-bit finaliser), one stream per channel from a 64-bit
state; the normal numbers come from the ziggurat method (Marsaglia & Tsang, "The ziggurat
method for generating random variables", J. Stat. Softw. 5(8), 2000) with 256 layers of equal
area ``V`` under ``exp(-x^2/2)`` and the tail beyond ``R`` by Marsaglia's exponential
rejection. Written for this project from those descriptions; the layer edges are computed at
import (:func:`ziggurat_tables`).

One 64-bit word per number in 99 % of the draws: 8 bits choose the layer, 1 bit the sign, 52
bits the abscissa; that case is tested inside the channel's loop and the rest (wedges, tail,
rejections) is a call. Measured ~3 ns per number here against ~12 ns per sample for numpy's
``standard_normal`` into a buffer plus the scaled add (benchmarks/simulate.py).
"""

from __future__ import annotations

import math

import numba
import numpy as np

#: layers of the ziggurat
ZIG_LAYERS = 256
#: start of the tail [-] and the area of each layer, for 256 layers (Marsaglia & Tsang 2000)
ZIG_R = 3.6541528853610088
ZIG_V = 4.92867323399e-3
_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)
_S30, _S27, _S31 = np.uint64(30), np.uint64(27), np.uint64(31)
_S8, _S11, _S12 = np.uint64(8), np.uint64(11), np.uint64(12)
_LOW8, _ONE = np.uint64(0xFF), np.uint64(1)
_TWO_M53 = 2.0 ** -53


def ziggurat_tables() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(k, w, f)`` of the 256-layer ziggurat: layer ``i`` spans ``0 <= x < x_i`` with
    ``x_0 = V/f(R)`` (the base layer, whose part beyond ``R`` stands for the tail),
    ``x_1 = R`` and ``x_{i+1} = f^-1(f(x_i) + V/x_i)``, ``x_256 = 0``, ``f(x) =
    exp(-x^2/2)``. ``k[i] = floor(2^52*x_{i+1}/x_i)`` (an abscissa ``m*2^-52*x_i`` with
    ``m < k[i]`` lies under the curve), ``w[i] = x_i*2^-52`` and ``f[i] = f(x_i)``
    (257 entries).

    Returns
    -------
    k : ndarray of uint64
        Acceptance thresholds.
    w : ndarray
        Layer widths scaled by 2^-52.
    f : ndarray
        exp(-x_i^2/2), 257 entries.

    References
    ----------
    .. [1] G. Marsaglia and W.W. Tsang, "The ziggurat method for generating random
       variables", J. Stat. Softw. 5(8) (2000) 1-7.
    """
    n = ZIG_LAYERS
    x = np.empty(n + 1)
    x[0] = ZIG_V / math.exp(-0.5 * ZIG_R * ZIG_R)
    x[1] = ZIG_R
    for i in range(1, n - 1):
        x[i + 1] = math.sqrt(-2.0 * math.log(ZIG_V / x[i] + math.exp(-0.5 * x[i] * x[i])))
    x[n] = 0.0
    k = np.array([math.floor(2.0 ** 52 * x[i + 1] / x[i]) for i in range(n)], dtype=np.int64)
    return k, x[:n] * 2.0 ** -52, np.exp(-0.5 * x * x)


_ZK, _ZW, _ZF = ziggurat_tables()


@numba.njit(cache=True, inline="always")
def _splitmix(state):
    """Next state and output of splitmix64."""
    state = state + _GOLDEN
    z = state
    z = (z ^ (z >> _S30)) * _M1
    z = (z ^ (z >> _S27)) * _M2
    return state, z ^ (z >> _S31)


@numba.njit(cache=True, inline="always")
def _open01(z):
    """A uniform number in (0, 1) from the top 53 bits of ``z``."""
    return (float(np.int64(z >> _S11)) + 0.5) * _TWO_M53


@numba.njit(cache=True)
def _normal_rest(state, r, zk, zw, zf):
    """The ziggurat from the 64-bit word ``r`` just drawn on: next state and one standard
    normal number (tables of :func:`ziggurat_tables`). :func:`_add_normal` tests the common
    case (the abscissa under the layer's inner rectangle) itself and calls this only for
    the ~1 % of words beyond it (wedge, tail, or a new word after a rejection)."""
    while True:
        i = np.intp(r & _LOW8)
        sgn = 1.0 - 2.0 * float(np.int64((r >> _S8) & _ONE))  # no branch on a random bit
        m = np.int64(r >> _S12)
        x = float(m) * zw[i]
        if m < zk[i]:
            return state, sgn * x
        if i == 0:  # the tail beyond R
            while True:
                state, r = _splitmix(state)
                a = -math.log(_open01(r)) / ZIG_R
                state, r = _splitmix(state)
                b = -math.log(_open01(r))
                if b + b > a * a:
                    break
            return state, sgn * (ZIG_R + a)
        state, r = _splitmix(state)
        if zf[i] + _open01(r) * (zf[i + 1] - zf[i]) < math.exp(-0.5 * x * x):
            return state, sgn * x
        state, r = _splitmix(state)


@numba.njit(cache=True, nogil=True)
def _add_normal(src, sd, state, zk, zw, zf, out):
    for k in range(out.size):
        state, r = _splitmix(state)
        i = np.intp(r & _LOW8)
        m = np.int64(r >> _S12)
        if m < zk[i]:  # 99 % of the words: the layer's rectangle, no further word
            z = (1.0 - 2.0 * float(np.int64((r >> _S8) & _ONE))) * (float(m) * zw[i])
        else:
            state, z = _normal_rest(state, r, zk, zw, zf)
        out[k] = src[k] + sd * z
    return state


@numba.njit(cache=True, nogil=True)
def _add_normal_pair(src1, sd1, state1, out1, src2, sd2, state2, out2, zk, zw, zf):
    """:func:`_add_normal` of two channels of equal length in one loop, each from its own
    stream (the same numbers and additions as two calls): the two generators' work
    overlaps. Returns both states."""
    for k in range(out1.size):
        state1, r = _splitmix(state1)
        i = np.intp(r & _LOW8)
        m = np.int64(r >> _S12)
        if m < zk[i]:
            z = (1.0 - 2.0 * float(np.int64((r >> _S8) & _ONE))) * (float(m) * zw[i])
        else:
            state1, z = _normal_rest(state1, r, zk, zw, zf)
        out1[k] = src1[k] + sd1 * z
        state2, r = _splitmix(state2)
        i = np.intp(r & _LOW8)
        m = np.int64(r >> _S12)
        if m < zk[i]:
            z = (1.0 - 2.0 * float(np.int64((r >> _S8) & _ONE))) * (float(m) * zw[i])
        else:
            state2, z = _normal_rest(state2, r, zk, zw, zf)
        out2[k] = src2[k] + sd2 * z
    return state1, state2


def add_normal_pair(src1: np.ndarray, sd1: float, state1: int, out1: np.ndarray,
                    src2: np.ndarray, sd2: float, state2: int,
                    out2: np.ndarray) -> tuple[int, int]:
    """:func:`add_normal` of two channels at once (the same values as two calls).

    Parameters
    ----------
    src1, src2 : ndarray
        The values, any unit; the same length.
    sd1, sd2 : float
        Standard deviations [unit of src1, src2].
    state1, state2 : int
        The streams' 64-bit states.
    out1, out2 : ndarray
        The outputs, shaped as ``src1``.

    Returns
    -------
    tuple of int
        The streams' states after their last numbers.

    Raises
    ------
    ValueError
        The arrays differ in shape.
    """
    if not (src1.shape == out1.shape == src2.shape == out2.shape):
        raise ValueError("add_normal_pair: the channels differ in shape")
    s1, s2 = _add_normal_pair(src1, float(sd1), np.uint64(state1), out1, src2, float(sd2),
                              np.uint64(state2), out2, _ZK, _ZW, _ZF)
    return int(s1), int(s2)


def add_normal(src: np.ndarray, sd: float, state: int, out: np.ndarray) -> int:
    """``out[k] = src[k] + sd*z_k`` with ``z_k`` standard normal from the splitmix64 stream
    at ``state`` (a 64-bit integer); ``src`` may be strided or ``out`` itself. Returns the
    stream's state after the last number.

    Parameters
    ----------
    src : ndarray
        The values, any unit.
    sd : float
        Standard deviation [unit of src].
    state : int
        The stream's 64-bit state.
    out : ndarray
        The output, same shape as ``src``.

    Returns
    -------
    int
        The stream's state after the last number.

    Raises
    ------
    ValueError
        ``src`` and ``out`` differ in shape.
    """
    if src.shape != out.shape:
        raise ValueError("add_normal: src and out differ in shape")
    return int(_add_normal(src, float(sd), np.uint64(state), _ZK, _ZW, _ZF, out))


def standard_normal(n: int, state: int) -> np.ndarray:
    """``n`` standard normal numbers from the splitmix64 stream at ``state`` (for tests).

    Parameters
    ----------
    n : int
        How many [-].
    state : int
        The stream's 64-bit state.

    Returns
    -------
    ndarray
        The numbers [-].
    """
    out = np.zeros(n)
    add_normal(out, 1.0, state, out)
    return out
