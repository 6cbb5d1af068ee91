"""The README and docs/accuracy.md name commands that exist: every benchmark script and test
file they cite is there, with the flags they give it, and every relative link resolves."""

from __future__ import annotations

import re
from pathlib import Path

import torquemod as tm

ROOT = Path(tm.__file__).parent.parent.parent


def _commands(text: str) -> list[str]:
    blocks = re.findall(r"```sh\n(.*?)```", text, re.S)
    return [line.split("#")[0].strip() for b in blocks for line in b.splitlines()
            if line.strip().startswith("python")]


def test_every_reproducing_command_exists():
    text = (ROOT / "docs" / "accuracy.md").read_text(encoding="utf-8")
    cmds = _commands(text)
    assert len(cmds) >= 13  # one or more per measured item
    for cmd in cmds:
        words = cmd.split()
        for path in (w for w in words if w.endswith(".py")):
            assert (ROOT / path).is_file(), cmd
        script = next((w for w in words if w.startswith("benchmarks/")), None)
        if script:
            source = (ROOT / script).read_text(encoding="utf-8")
            for flag in (w for w in words if w.startswith("--")):
                assert f'"{flag}"' in source, (cmd, flag)


def test_relative_links_resolve():
    for doc in (ROOT / "README.md", ROOT / "docs" / "accuracy.md"):
        for target in re.findall(r"\]\(([^)#:]+)(?:#[^)]*)?\)", doc.read_text(encoding="utf-8")):
            assert (doc.parent / target).exists(), (doc.name, target)
