"""The command line as a user meets it: help on every flag, exit codes of signals, shell
completion, a progress bar that does not guess the time left while kernels compile, and the
demo's words when mu is not determined."""

from __future__ import annotations

import argparse
import io
import os
import signal
import subprocess
import sys
import time

import pytest

from torquemod import cli
from torquemod._cli import parser as cli_parser
from torquemod._cli.output import why_they_differ
from torquemod._util.progress import WarmupBar


def _actions(parser, name="torquemod"):
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub_name, sub in action.choices.items():
                yield from _actions(sub, sub_name)
        elif not isinstance(action, argparse._HelpAction | argparse._VersionAction):
            yield name, action


def test_every_flag_has_help():
    missing = [(n, a.option_strings or a.dest) for n, a in _actions(cli.build_parser())
               if not (a.help and a.help.strip())]
    assert missing == []


@pytest.mark.parametrize(("sig", "code"), [(signal.SIGTERM, 143), (signal.SIGINT, 130)])
def test_signals_end_with_the_shells_exit_codes(monkeypatch, capsys, sig, code):
    def killed(_args):
        os.kill(os.getpid(), sig)
        time.sleep(5)  # the handler raises before this ends
        return 0

    monkeypatch.setattr(cli_parser, "cmd_report", killed)  # the parser binds the command
    # Ctrl-C as a terminal delivers it, also when this run was started with SIGINT ignored
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        assert cli.main(["report", "somewhere"]) == code
    finally:
        signal.signal(signal.SIGINT, previous)
    err = capsys.readouterr().err
    assert err.strip() == ("torquemod: terminated" if code == 143 else "torquemod: interrupted")
    assert signal.getsignal(signal.SIGTERM) is not None  # the previous handler is restored


def test_shell_completion_lists_subcommands_and_flags(tmp_path):
    out = tmp_path / "completions"
    env = {**os.environ, "_ARGCOMPLETE": "1", "COMP_LINE": "torquemod demo --q",
           "COMP_POINT": str(len("torquemod demo --q")),
           "_ARGCOMPLETE_STDOUT_FILENAME": str(out)}
    subprocess.run([sys.executable, "-m", "torquemod.cli"], env=env, check=True, timeout=120,
                   stdin=subprocess.DEVNULL, capture_output=True)
    words = set(out.read_text(encoding="utf-8").replace("\x0b", " ").split())
    assert {"--quick", "--quiet"} <= words and "--out" not in words


def test_no_time_left_before_the_first_item():
    buf = io.StringIO()
    bar = WarmupBar(total=10, desc="x", file=buf, mininterval=0)
    bar.refresh()
    assert "compiling kernels" in buf.getvalue() and "<" not in buf.getvalue()
    bar.update()
    bar.refresh()
    assert "<" not in buf.getvalue().rsplit("\r", 1)[-1]  # one item: no rate yet
    time.sleep(0.02)
    bar.update()
    bar.refresh()
    last = buf.getvalue().rsplit("\r", 1)[-1]
    bar.close()
    assert "<" in last and "compiling" not in last  # elapsed<remaining from item 2 on


def test_demo_words_when_mu_is_not_determined():
    truth = {"peak_coa": 0.2451, "mu0": 0.30, "mu_at_top_step": 0.262}
    text = why_they_differ({"mu": None, "mu_from_phase": None, "mu_lower_bound": 0.231,
                                 "mu_from_phase_interval_95": [0.2492, None]}, truth)
    assert "(-)" not in text and "mu >= 0.2492" in text and "not determined" in text
    text = why_they_differ({"mu": None, "mu_from_phase": 0.2505}, truth)
    # it names the value it explains (the phase's estimate is the available adhesion)
    assert "from the phase (0.2505)" in text and "(-)" not in text
