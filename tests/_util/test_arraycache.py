"""The disk cache of deterministic tables: built once, then loaded bit for bit; a damaged or
foreign file is rebuilt; an unwritable cache folder leaves the cache out. The creep-law
family's tables loaded from the cache equal freshly built ones bit for bit."""

from __future__ import annotations

import numpy as np

from torquemod._util.arraycache import cache_dir, cached_arrays


def _counted():
    calls = []

    def build():
        calls.append(1)
        return {"a": np.linspace(0.0, 1.0, 7) / 3.0, "b": np.array([np.nan, 1.5]),
                "ok": np.array([True, False])}

    return build, calls


def _same(x: dict, y: dict) -> bool:
    return set(x) == set(y) and all(
        x[k].dtype == y[k].dtype and x[k].shape == y[k].shape and x[k].tobytes() == y[k].tobytes()
        for k in x)


def test_built_once_then_loaded_bit_for_bit(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    build, calls = _counted()
    first = cached_arrays("t", {"n": 7}, build, names=("a", "b", "ok"))
    second = cached_arrays("t", {"n": 7}, build, names=("a", "b", "ok"))
    assert len(calls) == 1 and _same(first, second)
    files = list(cache_dir().iterdir())
    assert cache_dir() == tmp_path / "torquemod" and len(files) == 1  # no temporary left
    cached_arrays("t", {"n": 8}, build)  # another key (an upgrade): built again, old file gone
    assert len(calls) == 2 and len(list(cache_dir().iterdir())) == 1
    cached_arrays("u", {"n": 8}, build)  # other tables: their own file, beside
    assert len(calls) == 3 and len(list(cache_dir().iterdir())) == 2
    cached_arrays("t", {"n": 8}, build)  # still cached
    assert len(calls) == 3
    cached_arrays("t_x", {"n": 8}, build)  # a name that extends another's: no pruning across
    assert len(calls) == 4 and len(list(cache_dir().iterdir())) == 3


def test_a_damaged_file_is_rebuilt(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    build, calls = _counted()
    want = cached_arrays("t", {}, build)
    (path,) = cache_dir().iterdir()
    for damage in (b"not a zip file", path.read_bytes()[:200]):
        path.write_bytes(damage)
        assert _same(cached_arrays("t", {}, build), want)
    assert len(calls) == 3
    assert _same(cached_arrays("t", {}, build), want) and len(calls) == 3  # repaired
    # a file holding other arrays than promised is not used
    np.savez(path, __cache_key__=np.array("something else"), a=np.zeros(2))
    assert _same(cached_arrays("t", {}, build), want) and len(calls) == 4


def test_an_unwritable_cache_folder_leaves_the_cache_out(tmp_path, monkeypatch):
    (tmp_path / "torquemod").write_text("a file where the folder should be")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    build, calls = _counted()
    assert _same(cached_arrays("t", {}, build), build())
    cached_arrays("t", {}, build)  # built again: nothing was stored
    assert len(calls) == 3


def test_family_tables_from_the_cache_equal_fresh_ones(tmp_path, monkeypatch):
    """The swing tables (a few CPU-seconds) built into an empty cache, then loaded."""
    from torquemod.analysis import creeplaws
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    built = creeplaws.family_tables.__wrapped__(True)
    loaded = creeplaws.family_tables.__wrapped__(True)
    assert len(list(cache_dir().glob("creeplaw_family_swing-*.npz"))) == 1
    assert loaded.members == built.members
    for name in ("f_peak", "s", "ds", "swing", "beta_h", "falling"):
        a, b = getattr(built, name), getattr(loaded, name)
        assert a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes(), name
    creeplaws.family_tables.__wrapped__(False)  # the other table set keeps its own file
    assert len(list(cache_dir().glob("creeplaw_family_swing-*.npz"))) == 1
    assert len(list(cache_dir().glob("creeplaw_family-*.npz"))) == 1
