"""Progress bars whose first item may carry a one-off cost (numba compiling its kernels).

Until the first item is done, :class:`WarmupBar` shows ``compiling kernels…`` where tqdm
would show an estimate of the time left: that estimate would be the compilation's minutes
times the number of items. Afterwards the rate is taken from the items done since the first.
"""

from __future__ import annotations

from tqdm import tqdm

__all__ = ["WarmupBar"]

_WARMING = "{l_bar}{bar}| {n_fmt}/{total_fmt} [{elapsed}, compiling kernels…]"
_ESTIMATING = "{l_bar}{bar}| {n_fmt}/{total_fmt} [{elapsed}, estimating the time left…]"


class WarmupBar(tqdm):
    """A :class:`tqdm.tqdm` with no time-left estimate before the first item is done, and a
    rate over the items after it (the first may include compilation)."""

    def __init__(self, *args, **kwargs):
        self._first_done: tuple[float, float] | None = None  # (n, time) after the first item
        super().__init__(*args, **kwargs)

    def update(self, n=1):
        if self._first_done is None and n and not self.disable:
            self._first_done = (self.n + n, self._time())
        return super().update(n)

    @property
    def format_dict(self):
        d = super().format_dict
        if self._first_done is None:
            d["bar_format"] = _WARMING
            return d
        n0, t0 = self._first_done
        elapsed = self._time() - t0
        if self.n > n0 and elapsed > 0:
            d["rate"] = (self.n - n0) / elapsed
        else:
            d["bar_format"] = _ESTIMATING
        return d
