"""Outputs that never lose data (issue 9, item 3): torquemod._util.fsutil and the CLI around it.

Every rule is checked on what a user would lose: the bytes of the inputs and of folders that
are not torquemod's are compared before and after, and the output's parent is listed to see
that no temporary folder or lock file is left behind. Faults the test machine cannot produce
on demand (a full disk, a read-only target when running as root) are injected by replacing a
writer or a system call with one that raises the OSError the system would raise.
"""

from __future__ import annotations

import errno
import os
import shutil
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from torquemod._util import fsutil
from torquemod.cli import main
from torquemod.errors import OutputError
from torquemod.testing import write_synthetic_experiment

IS_ROOT = hasattr(os, "geteuid") and os.geteuid() == 0


# --------------------------------------------------------------------------- helpers

@pytest.fixture(scope="module")
def experiment(tmp_path_factory) -> Path:
    """A small synthetic experiment folder (4 steps x 2 cycles, CSV)."""
    d = tmp_path_factory.mktemp("safety") / "exp"
    write_synthetic_experiment(d, n_steps=4, n_cycles=2, seed=11)
    return d


@pytest.fixture(scope="module")
def results(experiment, tmp_path_factory) -> Path:
    """A results folder written by ``torquemod process --no-fit`` (copied per test)."""
    out = tmp_path_factory.mktemp("safety_res") / "res"
    assert main(["process", str(experiment), "--out", str(out), "--quiet", "--no-fit"]) == 0
    return out


@pytest.fixture
def res_copy(results, tmp_path) -> Path:
    dest = tmp_path / "res"
    shutil.copytree(results, dest)
    return dest


def snapshot(folder: Path) -> dict[str, bytes]:
    """Every file under ``folder`` (relative path -> bytes)."""
    return {str(p.relative_to(folder)): p.read_bytes()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def one_error_line(err: str, *needles: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("torquemod: error: "), err
    assert "Traceback" not in err
    for n in needles:
        assert n in lines[0], (n, lines[0])
    return lines[0]


def no_leftovers(parent: Path, *expected: str) -> None:
    """Only ``expected`` in ``parent``: no temporary folder, no lock file."""
    assert sorted(p.name for p in parent.iterdir()) == sorted(expected)


def raise_in(monkeypatch, obj, name: str, code: int, filename=None) -> None:
    """Replace ``obj.name`` by a function raising ``OSError(code)`` as the system would."""
    def fail(*_a, **_k):
        raise OSError(code, os.strerror(code), *([str(filename)] if filename else []))
    monkeypatch.setattr(obj, name, fail)


# --------------------------------------------------------------------------- inputs

def test_out_equal_to_or_holding_an_input_is_refused_also_with_force(experiment, tmp_path):
    manifest = experiment / "experiment.toml"
    link = tmp_path / "link"
    link.symlink_to(experiment, target_is_directory=True)
    before = snapshot(experiment)
    for out in (experiment, experiment.parent, link, manifest):  # is / holds / via a link
        with pytest.raises(OutputError, match="input") as info:
            with fsutil.atomic_dir(out, force=True, inputs=[manifest]):
                pytest.fail("the block must not run")
        assert str(out) in str(info.value)
    # an input folder inside the output counts too
    with pytest.raises(OutputError, match="holds the input"):
        fsutil.check_output_dir(experiment.parent, force=True, inputs=[experiment])
    assert snapshot(experiment) == before


def test_cli_process_into_the_experiment_folder_changes_nothing(experiment, tmp_path,
                                                                   capsys):
    exp = tmp_path / "exp"
    shutil.copytree(experiment, exp)
    before = snapshot(exp)
    rc = main(["process", str(exp / "experiment.toml"), "--out", str(exp), "--force",
               "--quiet"])
    assert rc == 2
    one_error_line(capsys.readouterr().err, str(exp))
    assert snapshot(exp) == before
    no_leftovers(tmp_path, "exp")


# --------------------------------------------------------------------------- --force

def test_force_refuses_a_foreign_folder(tmp_path):
    out = tmp_path / "thesis"
    out.mkdir()
    (out / "chapter1.tex").write_text("years of work", encoding="utf-8")
    with pytest.raises(OutputError) as info:
        with fsutil.atomic_dir(out, force=True):
            pass
    msg = str(info.value)
    assert str(out) in msg and "chapter1.tex" in msg and "force=True" in msg
    assert snapshot(out) == {"chapter1.tex": b"years of work"}
    no_leftovers(tmp_path, "thesis")


def test_cli_force_on_a_foreign_folder_keeps_it(experiment, tmp_path, capsys):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "notes.txt").write_text("keep", encoding="utf-8")
    rc = main(["process", str(experiment), "--out", str(out), "--force", "--quiet",
               "--no-fit"])
    assert rc == 2
    one_error_line(capsys.readouterr().err, str(out), "notes.txt")
    assert snapshot(out) == {"notes.txt": b"keep"}
    no_leftovers(tmp_path, "mine")


def test_force_replaces_a_torquemod_folder_whole(res_copy, tmp_path):
    assert (res_copy / fsutil.MARKER).is_file()  # written by process
    with fsutil.atomic_dir(res_copy, force=True) as tmp:
        (tmp / "steps.csv").write_text("new\n", encoding="utf-8")
    assert sorted(p.name for p in res_copy.iterdir()) == [fsutil.MARKER, "steps.csv"]
    assert (res_copy / "steps.csv").read_text(encoding="utf-8") == "new\n"
    no_leftovers(tmp_path, "res")


def test_force_on_an_old_results_folder_without_marker(res_copy, tmp_path):
    """A results folder from before the marker (only the layout's files) may be replaced;
    the same folder with a file of the user's in it may not."""
    (res_copy / fsutil.MARKER).unlink()
    with fsutil.atomic_dir(res_copy, force=True) as tmp:
        (tmp / "steps.csv").write_text("new\n", encoding="utf-8")
    assert (res_copy / "steps.csv").read_text(encoding="utf-8") == "new\n"
    (res_copy / fsutil.MARKER).unlink()
    (res_copy / "my_plot.py").write_text("x", encoding="utf-8")
    before = snapshot(res_copy)
    with pytest.raises(OutputError, match=r"my_plot\.py"):
        with fsutil.atomic_dir(res_copy, force=True):
            pass
    assert snapshot(res_copy) == before


def test_a_damaged_marker_does_not_count(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / fsutil.MARKER).write_text("not json", encoding="utf-8")
    (out / "data.bin").write_bytes(b"\0")
    with pytest.raises(OutputError, match="force=True replaces only"):
        fsutil.check_output_dir(out, force=True)


def test_empty_folder_is_used_without_force_and_marker_is_written(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    with fsutil.atomic_dir(out, kind="demo") as tmp:
        (tmp / "a.txt").write_text("a", encoding="utf-8")
    assert (out / "a.txt").read_text(encoding="utf-8") == "a"
    import json
    doc = json.loads((out / fsutil.MARKER).read_text(encoding="utf-8"))
    assert doc["format"] == "torquemod-output" and doc["kind"] == "demo"
    with pytest.raises(OutputError, match=r"already exists.*force=True"):
        fsutil.check_output_dir(out, force=False)


def test_output_that_is_a_file_or_a_link_is_refused(tmp_path):
    f = tmp_path / "f"
    f.write_text("x", encoding="utf-8")
    with pytest.raises(OutputError, match="not a folder"):
        fsutil.check_output_dir(f, force=True)
    link = tmp_path / "l"
    link.symlink_to(tmp_path / "elsewhere")
    with pytest.raises(OutputError, match="symbolic link"):
        fsutil.check_output_dir(link, force=True)
    assert f.read_text(encoding="utf-8") == "x"


# --------------------------------------------------------------------------- publishing

@pytest.fixture(params=["renameat2", "fallback"])
def rename_mode(request, monkeypatch):
    """Run a test with Linux renameat2 and with the portable fallback."""
    if request.param == "fallback":
        monkeypatch.setattr(fsutil, "_renameat2", lambda *a: False)
    elif fsutil._renameat2_fn is None:
        pytest.skip("no renameat2 in this libc (the fallback case still runs)")
    return request.param


def test_a_folder_that_appears_meanwhile_is_never_replaced(tmp_path, rename_mode):
    out = tmp_path / "out"
    for force in (False, True):
        with pytest.raises(OutputError, match=r"appeared|force=True replaces only"):
            with fsutil.atomic_dir(out, force=force) as tmp:
                (tmp / "result.txt").write_text("mine", encoding="utf-8")
                out.mkdir()  # someone else's folder appears while the run works
                (out / "theirs.txt").write_text("theirs", encoding="utf-8")
        assert snapshot(out) == {"theirs.txt": b"theirs"}
        no_leftovers(tmp_path, "out")
        shutil.rmtree(out)


def test_forced_replacement_swaps_and_leaves_no_old_copy(res_copy, tmp_path, rename_mode,
                                                         monkeypatch):
    if rename_mode == "renameat2":  # one exchange: the old folder is never moved aside,
        monkeypatch.setattr(os, "rename", None)  # so the target is never missing
    seen = []
    with fsutil.atomic_dir(res_copy, force=True) as tmp:
        (tmp / "x.txt").write_text("new", encoding="utf-8")
        seen.append(res_copy.is_dir())
    assert seen == [True] and (res_copy / "x.txt").is_file()
    assert not (res_copy / "steps.csv").exists()
    no_leftovers(tmp_path, "res")


def test_exchange_fallback_restores_the_old_folder_when_the_new_cannot_move_in(
        res_copy, tmp_path, monkeypatch):
    monkeypatch.setattr(fsutil, "_renameat2", lambda *a: False)
    before = snapshot(res_copy)
    real = fsutil._rename_noreplace

    def failing(src, dst):
        if Path(dst) == res_copy:
            raise OSError(errno.EIO, os.strerror(errno.EIO), str(dst))
        return real(src, dst)
    monkeypatch.setattr(fsutil, "_rename_noreplace", failing)
    with pytest.raises(OutputError, match="Input/output error"):
        with fsutil.atomic_dir(res_copy, force=True) as tmp:
            (tmp / "x.txt").write_text("new", encoding="utf-8")
    assert snapshot(res_copy) == before
    no_leftovers(tmp_path, "res")


def test_interrupted_block_leaves_the_old_folder_and_nothing_else(res_copy, tmp_path):
    before = snapshot(res_copy)
    for make in (fsutil.update_dir, lambda f: fsutil.atomic_dir(f, force=True)):
        with pytest.raises(KeyboardInterrupt):
            with make(res_copy) as tmp:
                (tmp / "steps.csv").write_text("half", encoding="utf-8")
                raise KeyboardInterrupt
        assert snapshot(res_copy) == before
        no_leftovers(tmp_path, "res")


# --------------------------------------------------------------------------- update_dir

def test_update_dir_swaps_in_the_modified_copy(res_copy, tmp_path):
    before = snapshot(res_copy)
    with fsutil.update_dir(res_copy) as tmp:
        assert snapshot(tmp) == before  # a full copy to modify
        (tmp / "fit.json").write_text("{}", encoding="utf-8")
        (tmp / "steps.csv").write_text("changed", encoding="utf-8")
        assert (res_copy / "steps.csv").read_bytes() == before["steps.csv"]  # not yet
    after = snapshot(res_copy)
    assert after["steps.csv"] == b"changed" and after["fit.json"] == b"{}"
    assert after["traces.npz"] == before["traces.npz"]
    no_leftovers(tmp_path, "res")


def test_update_dir_writing_a_copied_file_in_place_leaves_the_original(res_copy):
    """Writers that truncate and rewrite a file (np.savez does) must not reach the old
    folder through a shared (hard-linked) file."""
    original = (res_copy / "traces.npz").read_bytes()
    with pytest.raises(RuntimeError):
        with fsutil.update_dir(res_copy) as tmp:
            with open(tmp / "traces.npz", "r+b") as fh:
                fh.write(b"garbage")
            raise RuntimeError("failed after rewriting traces.npz")
    assert (res_copy / "traces.npz").read_bytes() == original


def test_update_dir_accepts_old_folders_and_refuses_others(res_copy, tmp_path):
    (res_copy / fsutil.MARKER).unlink()
    (res_copy / "my_notes.txt").write_text("n", encoding="utf-8")
    with fsutil.update_dir(res_copy) as tmp:  # steps.csv: results from before the marker
        (tmp / "fit.json").write_text("{}", encoding="utf-8")
    assert (res_copy / fsutil.MARKER).is_file() and (res_copy / "my_notes.txt").is_file()
    other = tmp_path / "photos"
    other.mkdir()
    (other / "a.jpg").write_bytes(b"jpg")
    with pytest.raises(OutputError, match="not a torquemod results folder"):
        with fsutil.update_dir(other):
            pytest.fail("the block must not run")
    with pytest.raises(OutputError, match="no such results folder"):
        with fsutil.update_dir(tmp_path / "missing"):
            pass
    assert snapshot(other) == {"a.jpg": b"jpg"}
    no_leftovers(tmp_path, "photos", "res")


# --------------------------------------------------------------------------- concurrency

def test_a_second_run_fails_at_once_while_the_first_holds_the_folder(tmp_path):
    out = tmp_path / "out"
    inside, release = threading.Event(), threading.Event()
    errors: list[BaseException] = []

    def first():
        try:
            with fsutil.atomic_dir(out) as tmp:
                (tmp / "first.txt").write_text("1", encoding="utf-8")
                inside.set()
                release.wait(10)
        except BaseException as exc:  # pragma: no cover - reported below
            errors.append(exc)

    t = threading.Thread(target=first)
    t.start()
    assert inside.wait(10)
    try:
        with pytest.raises(OutputError, match="another torquemod run is writing") as info:
            with fsutil.atomic_dir(out, force=True):
                pytest.fail("the second run must not start")
        assert str(out) in str(info.value)
    finally:
        release.set()
        t.join(10)
    assert not errors
    assert snapshot(out) == {"first.txt": b"1", fsutil.MARKER: (out / fsutil.MARKER)
                             .read_bytes()}
    no_leftovers(tmp_path, "out")  # lock file removed
    with pytest.raises(OutputError, match="already exists"):  # and now it is just occupied
        with fsutil.atomic_dir(out):
            pass


@pytest.mark.parametrize("force", [[], ["--force"]])
def test_two_concurrent_cli_runs_into_one_out_never_both_succeed(experiment, tmp_path,
                                                                  capsys, force):
    """Also with --force: the run holds the lock from its first check to its last rename,
    so the second fails at once instead of replacing the first's results."""
    out = tmp_path / "out"
    barrier = threading.Barrier(2)
    codes: list[int] = []

    def run():
        barrier.wait(10)
        codes.append(main(["process", str(experiment), "--out", str(out), "--quiet",
                           "--no-fit", *force]))

    threads = [threading.Thread(target=run) for _ in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(120)
    err = capsys.readouterr().err
    assert sorted(codes) == [0, 2], err
    assert str(out) in err and "Traceback" not in err
    assert (out / "steps.csv").is_file() and (out / fsutil.MARKER).is_file()
    no_leftovers(tmp_path, "out")


def test_lock_held_by_another_process_fails_report_at_once(res_copy, tmp_path, capsys):
    before = snapshot(res_copy)
    holder = subprocess.Popen(
        [sys.executable, "-c", "import sys; from torquemod._util.fsutil import output_lock\n"
         "with output_lock(sys.argv[1]):\n    print('locked', flush=True)\n"
         "    sys.stdin.readline()\n", str(res_copy)],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "locked"
        assert main(["report", str(res_copy), "--quiet"]) == 2
        one_error_line(capsys.readouterr().err, str(res_copy), "another torquemod run")
    finally:
        holder.communicate("\n", timeout=30)
    assert holder.returncode == 0
    assert snapshot(res_copy) == before
    no_leftovers(tmp_path, "res")


def test_a_stale_lock_file_does_not_block(tmp_path):
    """A lock file left by a killed run (no process holds its flock) is taken over."""
    (tmp_path / ".out.lock").write_text("12345\n", encoding="utf-8")
    with fsutil.atomic_dir(tmp_path / "out") as tmp:
        (tmp / "a").write_text("a", encoding="utf-8")
    no_leftovers(tmp_path, "out")


def test_lock_is_reentrant_in_one_thread(tmp_path):
    out = tmp_path / "out"
    with fsutil.output_lock(out), fsutil.atomic_dir(out) as tmp:
        (tmp / "a").write_text("a", encoding="utf-8")
    assert (out / "a").is_file()
    no_leftovers(tmp_path, "out")


# --------------------------------------------------------------------------- system faults

def test_disk_full_inside_the_block_is_one_output_error_and_leaves_nothing(tmp_path):
    out = tmp_path / "out"
    with pytest.raises(OutputError) as info:
        with fsutil.atomic_dir(out) as tmp:
            (tmp / "a.csv").write_text("a", encoding="utf-8")
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))  # no file name: pandas
    assert str(out) in str(info.value) and "No space left on device" in str(info.value)
    no_leftovers(tmp_path)


def test_error_naming_a_temporary_file_names_its_final_place(tmp_path):
    out = tmp_path / "out"
    with pytest.raises(OutputError) as info:
        with fsutil.atomic_dir(out) as tmp:
            raise OSError(errno.EDQUOT, os.strerror(errno.EDQUOT), str(tmp / "traces.npz"))
    assert str(info.value).startswith(f"{out / 'traces.npz'}: ")
    assert ".tmp-" not in str(info.value)


def test_cli_process_disk_full_while_writing(experiment, tmp_path, capsys, monkeypatch):
    import numpy as np
    raise_in(monkeypatch, np, "savez", errno.ENOSPC)
    out = tmp_path / "out"
    rc = main(["process", str(experiment), "--out", str(out), "--quiet", "--no-fit"])
    assert rc == 2
    one_error_line(capsys.readouterr().err, str(out), "No space left on device")
    no_leftovers(tmp_path)


def test_cli_report_disk_full_keeps_the_old_folder(res_copy, tmp_path, capsys, monkeypatch):
    from matplotlib.figure import Figure
    raise_in(monkeypatch, Figure, "savefig", errno.ENOSPC)
    before = snapshot(res_copy)
    assert main(["report", str(res_copy), "--quiet"]) == 2
    one_error_line(capsys.readouterr().err, str(res_copy), "No space left on device")
    assert snapshot(res_copy) == before
    no_leftovers(tmp_path, "res")


@pytest.fixture
def readonly(monkeypatch):
    """Make folders read-only: chmod 0o555, and when running as root (where the mode does not
    stop writes) also make the system calls that create entries in them raise EACCES."""
    dirs: list[Path] = []

    def make(folder: Path) -> Path:
        folder.chmod(0o555)
        dirs.append(folder.resolve())
        return folder

    if IS_ROOT:
        def guarded(func):
            def wrapper(path, *args, **kwargs):
                p = Path(os.fsdecode(path)).absolute()
                if any(p.parent == d for d in dirs):
                    raise PermissionError(errno.EACCES, os.strerror(errno.EACCES), str(path))
                return func(path, *args, **kwargs)
            return wrapper
        real_access = os.access
        monkeypatch.setattr(os, "open", guarded(os.open))
        monkeypatch.setattr(os, "mkdir", guarded(os.mkdir))
        monkeypatch.setattr(os, "access", lambda p, mode, **k: (
            False if mode & os.W_OK and Path(p).absolute() in dirs else real_access(p, mode)))
    yield make
    for d in dirs:
        d.chmod(0o755)


def test_cli_process_into_a_read_only_parent(experiment, tmp_path, capsys, readonly):
    (tmp_path / "ro").mkdir()
    parent = readonly(tmp_path / "ro")
    out = parent / "out"
    rc = main(["process", str(experiment), "--out", str(out), "--quiet", "--no-fit"])
    assert rc == 2
    one_error_line(capsys.readouterr().err, str(out), "Permission denied")
    assert list(parent.iterdir()) == []


def test_cli_report_on_a_read_only_results_folder(res_copy, tmp_path, capsys, readonly):
    before = snapshot(res_copy)
    readonly(res_copy)
    assert main(["report", str(res_copy), "--quiet"]) == 2
    one_error_line(capsys.readouterr().err, str(res_copy), "Permission denied")
    assert snapshot(res_copy) == before
    no_leftovers(tmp_path, "res")


def test_read_only_file_system_is_named(tmp_path, monkeypatch):
    real = os.open

    def erofs(path, *args, **kwargs):
        if Path(os.fsdecode(path)).parent == tmp_path:
            raise OSError(errno.EROFS, os.strerror(errno.EROFS), str(path))
        return real(path, *args, **kwargs)
    monkeypatch.setattr(os, "open", erofs)
    with pytest.raises(OutputError, match="Read-only file system") as info:
        with fsutil.atomic_dir(tmp_path / "out"):
            pass
    assert str(tmp_path / "out") in str(info.value)


@pytest.mark.parametrize("exc, code", [
    (OSError(errno.ENOSPC, "No space left on device", "/r/steps.csv"), 2),
    (OSError(errno.EDQUOT, "Disk quota exceeded"), 2),
    (OSError("Unable to synchronously create file (unable to open file: name = '/r/x.h5', "
             "errno = 28, error message = 'No space left on device', flags = 13)"), 2),
    (ValueError("a writer's own error"), 3),
])
def test_main_maps_system_errors_to_exit_2(experiment, tmp_path, capsys, monkeypatch, exc,
                                           code):
    """An OSError of the system escaping from deep inside a writer (here injected in place
    of the results writer, also wrapped in another exception) is exit 2 with one line; any
    other exception stays an internal error (3)."""
    import torquemod.api as api

    def failing(*_a, **_k):
        if code == 3:
            raise exc
        raise RuntimeError("while writing") from exc
    monkeypatch.setattr(api, "save", failing)
    out = tmp_path / "out"
    rc = main(["process", str(experiment), "--out", str(out), "--quiet", "--no-fit"])
    err = capsys.readouterr().err
    assert rc == code, err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    if code == 2:
        assert "No space left" in err or "quota" in err
        assert ("/r/" in err) or str(out) in err


def test_environment_error_finds_the_cause():
    inner = OSError(errno.EROFS, "Read-only file system", "/x")
    try:
        try:
            raise inner
        except OSError:
            raise KeyError("k")  # noqa: B904 - implicit context, as libraries do
    except KeyError as outer:
        assert fsutil.environment_error(outer) is inner
    assert fsutil.environment_error(OSError(errno.ECONNRESET, "reset")) is None
    assert fsutil.environment_error(ValueError("x")) is None


# --------------------------------------------------------------------------- convert

@pytest.fixture
def h5_input(experiment, tmp_path) -> Path:
    from torquemod.io.convert import convert_file
    src = next(experiment.glob("*.csv"))
    return convert_file(src, tmp_path / "in.h5")


def test_cli_convert_refuses_an_existing_output_without_force(experiment, h5_input, tmp_path,
                                                              capsys):
    src = next(experiment.glob("*.csv"))
    out = tmp_path / "existing.h5"
    out.write_bytes(b"precious")
    assert main(["convert", str(src), "--out", str(out)]) == 2
    one_error_line(capsys.readouterr().err, str(out), "already exists", "--force")
    assert out.read_bytes() == b"precious"
    assert main(["convert", str(src), "--out", str(out), "--force"]) == 0
    capsys.readouterr()
    assert out.read_bytes()[:8] == b"\x89HDF\r\n\x1a\n"
    no_leftovers(tmp_path, "existing.h5", "in.h5")


def test_cli_convert_force_never_overwrites_its_input(h5_input, tmp_path, capsys):
    before = h5_input.read_bytes()
    hard = tmp_path / "hard.h5"
    os.link(h5_input, hard)
    for out in (h5_input, hard):
        assert main(["convert", str(h5_input), "--out", str(out), "--force"]) == 2
        one_error_line(capsys.readouterr().err, str(out), "is the input")
    assert h5_input.read_bytes() == before
    no_leftovers(tmp_path, "in.h5", "hard.h5")


def test_cli_convert_disk_full_h5py_style(experiment, tmp_path, capsys, monkeypatch):
    import torquemod.io.convert as convert

    def full(path, *_a, **_k):
        Path(path).write_bytes(b"half")
        raise OSError("Unable to synchronously create dataset (file write failed: errno = "
                      "28, error message = 'No space left on device')")
    monkeypatch.setattr(convert, "write_hdf5", full)
    out = tmp_path / "o.h5"
    assert main(["convert", str(next(experiment.glob("*.csv"))), "--out", str(out)]) == 2
    one_error_line(capsys.readouterr().err, str(out), "No space left on device")
    no_leftovers(tmp_path)


def test_cli_convert_experiment_force_on_a_foreign_folder(experiment, tmp_path, capsys):
    out = tmp_path / "conv"
    out.mkdir()
    (out / "mine.txt").write_text("m", encoding="utf-8")
    manifest = experiment / "experiment.toml"
    assert main(["convert", "--manifest", str(manifest), "--out", str(out), "--force"]) == 2
    one_error_line(capsys.readouterr().err, str(out), "mine.txt")
    assert snapshot(out) == {"mine.txt": b"m"}
    (out / "mine.txt").unlink()
    assert main(["convert", "--manifest", str(manifest), "--out", str(out)]) == 0  # empty
    assert main(["convert", "--manifest", str(manifest), "--out", str(out), "--force"]) == 0
    capsys.readouterr()
    assert (out / "experiment.toml").is_file() and (out / fsutil.MARKER).is_file()
    no_leftovers(tmp_path, "conv")


def test_cli_convert_one_file_with_the_manifest_channels(experiment, tmp_path, capsys):
    """INPUT with --manifest converts INPUT alone, read with the manifest's [channels]
    (docs/format.md), not the whole experiment."""
    from torquemod.io.recording import read_recording
    src = sorted(experiment.glob("*.csv"))[0]
    out = tmp_path / "one.h5"
    assert main(["convert", str(src), "--manifest", str(experiment / "experiment.toml"),
                 "--out", str(out)]) == 0
    assert capsys.readouterr().out.strip() == f"written {out}"
    a, b = read_recording(src), read_recording(out)
    assert a.fs_hz == pytest.approx(b.fs_hz, rel=1e-12)
    assert (a.channels["torque_nm"] == b.channels["torque_nm"]).all()


# --------------------------------------------------------------------------- no traceback

@pytest.mark.parametrize("case", ["convert_onto_input", "process_into_experiment"])
def test_subprocess_prints_one_line_and_no_traceback(case, experiment, h5_input, tmp_path):
    if case == "convert_onto_input":
        argv = ["convert", str(h5_input), "--out", str(h5_input), "--force"]
    else:
        argv = ["process", str(experiment / "experiment.toml"), "--out", str(experiment),
                "--force", "--quiet"]
    before = snapshot(experiment)
    proc = subprocess.run([sys.executable, "-m", "torquemod.cli", *argv],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2, proc.stderr
    one_error_line(proc.stderr)
    assert "Traceback" not in proc.stdout
    assert snapshot(experiment) == before


def test_unwritable_out_is_refused_before_any_work(experiment, tmp_path, capsys):
    """An --out below a file, or in a system folder, fails at once (exit 2, one line),
    not after processing."""
    f = tmp_path / "file"
    f.write_text("x", encoding="utf-8")
    for out, reason in ((f / "sub" / "out", "Not a directory"),
                        (Path("/dev/null/out"), "Not a directory")):
        with pytest.raises(OutputError, match=reason):
            fsutil.check_output_dir(out, force=False)
        assert main(["process", str(experiment), "--out", str(out), "--quiet",
                     "--no-fit"]) == 2
        one_error_line(capsys.readouterr().err, str(out), reason)
    assert f.read_text(encoding="utf-8") == "x"


def test_failed_run_leaves_no_parent_folders(experiment, tmp_path, capsys, monkeypatch):
    import numpy as np
    raise_in(monkeypatch, np, "savez", errno.ENOSPC)
    out = tmp_path / "a" / "b" / "out"
    assert main(["process", str(experiment), "--out", str(out), "--quiet", "--no-fit"]) == 2
    one_error_line(capsys.readouterr().err, "No space left on device")
    no_leftovers(tmp_path)


def test_sigterm_during_the_write_leaves_nothing(experiment, tmp_path):
    """A run stopped by SIGTERM while it writes (sent from inside the writer, so the moment
    is exact) removes its temporary folder and lock file and names the interruption."""
    out = tmp_path / "out"
    script = ("import os, signal, sys\n"
              "import torquemod._util.fsutil as f\n"
              "from torquemod.cli import main\n"
              "f.write_marker = lambda *a, **k: os.kill(os.getpid(), signal.SIGTERM)\n"
              "sys.exit(main(sys.argv[1:]))\n")
    proc = subprocess.run([sys.executable, "-c", script, "process", str(experiment),
                           "--out", str(out), "--quiet", "--no-fit"],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 143, proc.stderr  # 128 + SIGTERM, as a shell reports it
    assert proc.stderr.strip() == "torquemod: terminated"
    no_leftovers(tmp_path)


def test_temporary_folders_of_a_killed_run_are_swept(tmp_path):
    """A run killed with SIGKILL leaves ``.out.tmp-XXXXXXXX``; the next run into the same
    --out (holding the lock, so no run owns it) removes it; other names are kept."""
    stale = tmp_path / ".out.tmp-abcd1234"
    (stale / "sub").mkdir(parents=True)
    other = tmp_path / ".outer.tmp-abcd1234"
    other.mkdir()
    with fsutil.atomic_dir(tmp_path / "out") as tmp:
        (tmp / "a").write_text("a", encoding="utf-8")
    no_leftovers(tmp_path, "out", ".outer.tmp-abcd1234")


def test_ctrl_c_during_processing_leaves_nothing(experiment, tmp_path, capsys, monkeypatch):
    import torquemod.api as api

    def interrupted(*_a, **_k):
        raise KeyboardInterrupt
    monkeypatch.setattr(api, "process", interrupted)
    out = tmp_path / "new" / "out"
    assert main(["process", str(experiment), "--out", str(out), "--quiet"]) == 130
    assert capsys.readouterr().err.strip() == "torquemod: interrupted"
    no_leftovers(tmp_path)  # no lock file, no parent folder made for it


def test_ctrl_c_while_report_writes_keeps_the_old_folder(res_copy, tmp_path, capsys,
                                                         monkeypatch):
    import torquemod.results.folder as layout

    def interrupted(folder, *_a, **_k):
        (Path(folder) / "report.html").write_text("half", encoding="utf-8")
        raise KeyboardInterrupt
    monkeypatch.setattr(layout, "write_report", interrupted)
    before = snapshot(res_copy)
    assert main(["report", str(res_copy), "--quiet"]) == 130
    capsys.readouterr()
    assert snapshot(res_copy) == before
    no_leftovers(tmp_path, "res")
