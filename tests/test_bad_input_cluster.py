"""`torquemod fleet` and `torquemod sweep` under bad cluster options, bad sweep files and
outputs, interrupts and faults.

Bad options and inputs: exit 2, one line, nothing at --out, fast. Interrupts: Ctrl-C (SIGINT
to the process group, as a terminal sends it) and SIGTERM end with one line and exit 130 /
143, the workers stop quietly, no ``dask-scratch-space`` is left in the temporary folder,
and a rerun resumes. Faults inside the command run its tasks on an in-process cluster (so
that the injected fault reaches them).
"""

from __future__ import annotations

import contextlib
import errno
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from test_outputs_safety import (  # noqa: F401
    experiment,
    no_leftovers,
    one_error_line,
    raise_in,
    readonly,
    snapshot,
)
from torquemod._util import daskutil
from torquemod.cli import main
from torquemod.errors import InputError
from torquemod.sweep.run import run_sweep
from torquemod.sweep.spec import parse_sweep

THEORY = """mode = "theory"
[grid]
modulation.frequency_hz = [1.0, 2.0]
"""


def _closed_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture
def inputs(tmp_path, experiment):  # noqa: F811
    """``{"fleet": [experiment folder], "sweep": [sweep file]}`` in tmp_path/in."""
    folder = tmp_path / "in"
    folder.mkdir()
    (folder / "sweep.toml").write_text(THEORY, encoding="utf-8")
    return {"fleet": [str(experiment)], "sweep": [str(folder / "sweep.toml")]}


def _cmd(command: str, inputs, out, *extra) -> list[str]:
    return [command, *inputs[command], "--out", str(out), "--quiet", *extra]


# --------------------------------------------------------------------------- cluster options

BAD_OPTIONS = [
    ("no_port", ["--scheduler", "not-an-address"], ("not-an-address", "HOST:PORT")),
    ("bad_port", ["--scheduler", "tcp://host:99999"], ("HOST:PORT",)),
    ("unknown_scheme", ["--scheduler", "ftp://host:8786"], ("ftp://",)),
    ("zero_workers", ["--workers", "0"], ("--workers", "1 or more")),
    ("negative_workers", ["--workers", "-1"], ("--workers",)),
]


@pytest.mark.parametrize("command", ["fleet", "sweep"])
@pytest.mark.parametrize("extra,words", [pytest.param(c[1], c[2], id=c[0])
                                         for c in BAD_OPTIONS])
def test_bad_cluster_option_refused_at_once(command, inputs, tmp_path, capsys, extra, words):
    t0 = time.perf_counter()
    assert main(_cmd(command, inputs, tmp_path / "out", *extra)) == 2
    assert time.perf_counter() - t0 < 5.0  # before any cluster or work (generous: load)
    one_error_line(capsys.readouterr().err, *words)
    no_leftovers(tmp_path, "in")


@pytest.mark.parametrize("command", ["fleet", "sweep"])
def test_unreachable_scheduler_fails_within_the_timeout(command, inputs, tmp_path, capsys):
    address = f"tcp://127.0.0.1:{_closed_port()}"
    t0 = time.perf_counter()
    rc = main(_cmd(command, inputs, tmp_path / "out", "--scheduler", address,
                   "--connect-timeout", "1"))
    elapsed = time.perf_counter() - t0
    assert rc == 2
    one_error_line(capsys.readouterr().err, address, "within 1 s")
    assert elapsed < 10.0, elapsed  # 1 s of waiting, the rest is importing Dask under load
    no_leftovers(tmp_path, "in")


def test_the_help_states_the_sweep_limit_in_force():
    from torquemod._cli.commands import MAX_POINTS as _MAX_POINTS
    from torquemod.sweep.spec import MAX_POINTS
    assert _MAX_POINTS == MAX_POINTS


def test_default_connect_timeout_is_at_most_ten_seconds():
    assert 0 < daskutil.CONNECT_TIMEOUT_S <= 10.0
    assert daskutil.check_scheduler("10.0.0.5:8786") == "tcp://10.0.0.5:8786"
    assert daskutil.check_scheduler("tls://[::1]:8786") == "tls://[::1]:8786"


# --------------------------------------------------------------------------- sweep inputs

def test_sweep_out_may_not_hold_the_sweep_file_or_its_base(tmp_path, capsys):
    folder = tmp_path / "study"
    (folder / "bases").mkdir(parents=True)
    (folder / "bases" / "rig.toml").write_text("[modulation]\namplitude_nm = 4.0\n",
                                               encoding="utf-8")
    sweep = tmp_path / "sweep.toml"
    sweep.write_text('base = "study/bases/rig.toml"\n' + THEORY, encoding="utf-8")
    before = snapshot(tmp_path)
    for out in (tmp_path, folder, folder / "bases"):
        assert main(["sweep", str(sweep), "--out", str(out), "--quiet"]) == 2
        one_error_line(capsys.readouterr().err, str(out), "holds the sweep's input")
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize("base,line,words", [
    ("train", "mass_share_kg = -21000.0", ("vehicle.mass_share_kg",)),
    ("train", "wheel_radius_m = 0.0", ("vehicle.wheel_radius_m",)),
    ("rig", "amplitude_nm = nan", ("modulation.amplitude_nm",)),
])
def test_a_bad_base_is_refused_when_the_sweep_is_read(tmp_path, capsys, base, line, words):
    from torquemod.twins.train import default_train_config_text
    from torquemod.twins.vtrack.simulate import default_config_text
    text = default_train_config_text() if base == "train" else default_config_text()
    key = line.split(" = ")[0]
    lines = [line if ln.split(" = ")[0].strip() == key else ln for ln in text.splitlines()]
    (tmp_path / "base.toml").write_text("\n".join(lines) + "\n", encoding="utf-8")
    sweep = tmp_path / "sweep.toml"
    sweep.write_text('base = "base.toml"\n[grid]\ntest.modulation_amplitude_nm = [800.0]\n'
                     if base == "train" else 'base = "base.toml"\n' + THEORY, encoding="utf-8")
    assert main(["sweep", str(sweep), "--out", str(tmp_path / "out"), "--quiet"]) == 2
    one_error_line(capsys.readouterr().err, str(tmp_path / "base.toml"), *words)
    no_leftovers(tmp_path, "base.toml", "sweep.toml")


def test_a_large_grid_states_its_size_and_is_refused_unless_asked(tmp_path, capsys):
    values = ", ".join(str(float(v)) for v in range(1, 11))
    text = "mode = \"theory\"\n[grid]\n" + "".join(
        f"{k} = [{values}]\n" for k in ("modulation.frequency_hz", "modulation.amplitude_nm",
                                         "rig.speed_km_h", "rig.normal_load_n",
                                         "contact.mu0", "contact.k_a"))
    sweep = tmp_path / "big.toml"
    sweep.write_text(text, encoding="utf-8")
    t0 = time.perf_counter()
    assert main(["sweep", str(sweep), "--out", str(tmp_path / "out"), "--quiet"]) == 2
    assert time.perf_counter() - t0 < 5.0  # the million points are never built
    one_error_line(capsys.readouterr().err, "1000000 points", "10 x 10", "--max-points")
    assert main(["sweep", str(sweep), "--out", str(tmp_path / "out"), "--quiet",
                 "--max-points", "5000"]) == 2
    one_error_line(capsys.readouterr().err, "limit of 5000")
    assert len(parse_sweep(THEORY, max_points=2).points) == 2  # at the limit: accepted
    with pytest.raises(InputError, match="more than the limit of 1"):
        parse_sweep(THEORY, max_points=1)
    no_leftovers(tmp_path, "big.toml")


def test_a_changed_study_never_mixes_with_the_old_one(tmp_path):
    """A changed grid is refused in the old folder; --force starts a new study (the old
    points gone); a grown grid resumes (the finished points skipped)."""
    out = tmp_path / "out"
    first = run_sweep(parse_sweep(THEORY), out, in_process=True, report=False)
    assert first.count("done") == 2
    changed = parse_sweep(THEORY.replace("[1.0, 2.0]", "[1.0, 3.0]"))
    before = snapshot(out)
    with pytest.raises(InputError, match="another study"):
        run_sweep(changed, out, in_process=True, report=False)
    assert snapshot(out) == before
    res = run_sweep(changed, out, in_process=True, report=False, force=True)
    ids = {p.point_id for p in changed.points}
    assert {p.name.split("=")[1] for p in (out / "points").iterdir()} == ids
    assert set(res.table["point_id"]) == ids
    grown = parse_sweep(THEORY.replace("[1.0, 2.0]", "[1.0, 3.0, 4.0]"))
    res = run_sweep(grown, out, in_process=True, report=False)
    assert res.count("skipped") == 2 and res.count("done") == 1
    other_mode = parse_sweep(THEORY.replace("[1.0, 2.0]", "[1.0, 3.0, 4.0]")
                             + "[steps]\nfractions_of_peak = [0.0, 0.5]\n")
    with pytest.raises(InputError, match="another study"):
        run_sweep(other_mode, out, in_process=True, report=False)


# --------------------------------------------------------------------------- interrupts

def _scratch_free(tmp: Path) -> None:
    assert not [p for p in tmp.rglob("*") if "dask-scratch-space" in p.name]
    assert not list(tmp.glob("torquemod-dask-*"))


def _start(args, tmp: Path, cwd: Path) -> subprocess.Popen:
    """The command in its own session (a process group, as a terminal's job), with this
    torquemod importable from ``cwd`` and ``tmp`` as its temporary folder."""
    import torquemod
    path = os.pathsep.join([str(Path(torquemod.__file__).resolve().parents[1]),
                            os.environ.get("PYTHONPATH", "")])
    env = dict(os.environ, TMPDIR=str(tmp), PYTHONPATH=path)
    return subprocess.Popen([sys.executable, "-m", "torquemod.cli", *args], cwd=cwd, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True, preexec_fn=_default_sigint)


def _default_sigint() -> None:
    """Ctrl-C's default action in the child even when this test run was started with SIGINT
    ignored (``nohup``, a background job without job control): a terminal's job has it."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _wait_for(pred, timeout: float) -> None:
    end = time.monotonic() + timeout
    while not pred():
        if time.monotonic() > end:
            raise AssertionError("timed out")
        time.sleep(0.2)

def _stop_when(proc, ready, stop) -> tuple[str, str]:
    """Wait until ``ready()`` (at most 240 s), call ``stop()`` and collect the process's
    output; the process group is killed whatever happens."""
    try:
        _wait_for(ready, 240)
        stop()
        return proc.communicate(timeout=120)
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)



def test_sweep_ctrl_c_stops_quietly_and_resumes(tmp_path):
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    values = ", ".join(f"{1.0 + 0.1 * i:.1f}" for i in range(12))
    (tmp_path / "s.toml").write_text(f"mode = \"theory\"\n[grid]\nmodulation.frequency_hz = "
                                     f"[{values}]\n", encoding="utf-8")
    args = ["sweep", "s.toml", "--out", "out", "--workers", "1"]
    proc = _start([*args, "--quiet"], tmp, tmp_path)
    out, err = _stop_when(  # interrupted once some points are done
        proc, lambda: len(list((tmp_path / "out" / "points").glob("point=*"))) >= 2,
        lambda: os.killpg(proc.pid, signal.SIGINT))  # as the terminal: the workers get it too
    assert proc.returncode == 130, err
    assert "Traceback" not in err + out
    assert err.strip().splitlines()[-1] == "torquemod: interrupted"
    assert len(err.strip().splitlines()) <= 2, err  # the dashboard's address, then that
    _scratch_free(tmp)
    done = len(list((tmp_path / "out" / "points").glob("point=*")))
    rerun = _start(args, tmp, tmp_path)
    out, err = rerun.communicate(timeout=400)
    assert rerun.returncode == 0, err
    assert f"{done} finished" in err  # the plan said what was done already
    assert f"{done} unchanged (skipped)" in out
    _scratch_free(tmp)


def test_fleet_sigterm_exits_143_quietly(tmp_path, experiment):  # noqa: F811
    """(Resuming after an interrupt: test_interrupt_while_writing_then_resume.)"""
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    runs = tmp_path / "runs"
    for i in range(3):
        (runs / f"r{i}").mkdir(parents=True)
        for p in experiment.iterdir():
            (runs / f"r{i}" / p.name).write_bytes(p.read_bytes())
    args = ["fleet", "runs", "--out", "out", "--workers", "1", "--quiet"]
    proc = _start(args, tmp, tmp_path)
    out, err = _stop_when(
        proc, lambda: len(list((tmp_path / "out" / "_state").glob("*.json"))) >= 1,
        lambda: proc.send_signal(signal.SIGTERM))  # a job scheduler's stop: this process only
    assert proc.returncode == 143, err
    assert "Traceback" not in err + out
    assert err.strip().splitlines()[-1] == "torquemod: terminated"
    _scratch_free(tmp)


# --------------------------------------------------------------------------- faults

@pytest.fixture
def threaded_cluster(monkeypatch):
    """fleet and sweep on an in-process cluster of one thread (the injected fault reaches
    the tasks)."""
    @contextlib.contextmanager
    def client(scheduler=None, n_workers=None, on_dashboard=None, **_kw):
        from dask.distributed import Client, LocalCluster
        with LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                          dashboard_address=None) as cluster, Client(cluster) as c:
            yield c
    monkeypatch.setattr(daskutil, "dask_client", client)


@pytest.mark.parametrize("command", ["fleet", "sweep"])
def test_disk_full_is_one_line(command, inputs, tmp_path, capsys, monkeypatch,
                               threaded_cluster):
    import torquemod.fleet.run as fleet
    import torquemod.sweep.run as sweep_run
    if command == "fleet":
        raise_in(monkeypatch, fleet, "_write_csv", errno.ENOSPC)
    else:
        raise_in(monkeypatch, sweep_run, "_write_parquet", errno.ENOSPC)
    out = tmp_path / "out"
    assert main(_cmd(command, inputs, out)) == 2
    one_error_line(capsys.readouterr().err, "No space left on device")


@pytest.mark.parametrize("command", ["fleet", "sweep"])
def test_interrupt_while_writing_then_resume(command, inputs, tmp_path, capsys, monkeypatch,
                                             threaded_cluster):
    import torquemod.fleet.run as fleet
    import torquemod.sweep.run as sweep_run

    def interrupted(*_a, **_k):
        raise KeyboardInterrupt
    with monkeypatch.context() as m:
        if command == "fleet":
            m.setattr(fleet, "prune_empty", interrupted)
        else:
            m.setattr(sweep_run, "assemble", interrupted)
        assert main(_cmd(command, inputs, tmp_path / "out")) == 130
        assert capsys.readouterr().err.strip() == "torquemod: interrupted"
    assert main(_cmd(command, inputs, tmp_path / "out")) == 0
    n = {"fleet": 1, "sweep": 2}[command]  # one experiment; two points
    assert f"{n} unchanged (skipped)" in capsys.readouterr().out


@pytest.mark.parametrize("command", ["fleet", "sweep"])
def test_read_only_target(command, inputs, tmp_path, capsys, readonly):  # noqa: F811
    (tmp_path / "ro").mkdir()
    parent = readonly(tmp_path / "ro")
    assert main(_cmd(command, inputs, parent / "out")) == 2
    one_error_line(capsys.readouterr().err, "Permission denied")
    assert list(parent.iterdir()) == []


@pytest.mark.parametrize("command", ["fleet", "sweep"])
def test_out_that_is_a_file_is_refused_before_any_cluster(command, inputs, tmp_path, capsys):
    (tmp_path / "out").write_text("x", encoding="utf-8")
    assert main(_cmd(command, inputs, tmp_path / "out")) == 2
    one_error_line(capsys.readouterr().err, "not a folder")
    assert (tmp_path / "out").read_text(encoding="utf-8") == "x"


@pytest.mark.parametrize("args", [["sweep", "s.toml", "--out", "o", "--max-points", "0"],
                                  ["fleet", "r", "--out", "o", "--connect-timeout", "-1"],
                                  ["sweep", "s.toml"]])
def test_a_command_line_that_cannot_be_parsed_is_one_line(args, capsys):
    with pytest.raises(SystemExit) as info:
        main(args)
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "--help" in err, err
