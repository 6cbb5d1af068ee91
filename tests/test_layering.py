"""The package's layering (docs/layout.md), checked on every run of the suite:

* the import-linter contracts of pyproject.toml (``[tool.importlinter]``): each stage imports
  only the stages below it, no measurement package imports the twins, nothing imports the
  command line;
* no import cycle between the modules of any one package, nor between packages;
* no private name (``_x``) imported from outside the package that holds it.

Imports inside functions count as well as those at the top of a module.
"""

from __future__ import annotations

import ast
import os
import subprocess
import sys
from pathlib import Path

import pytest

import torquemod

SRC = Path(torquemod.__file__).resolve().parent.parent
ROOT = SRC.parent


def _modules() -> dict[str, Path]:
    out = {}
    for path in sorted((SRC / "torquemod").rglob("*.py")):
        parts = path.relative_to(SRC).with_suffix("").parts
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


MODULES = _modules()


def _is_package(name: str) -> bool:
    return MODULES[name].name == "__init__.py"


def _imports(name: str) -> list[tuple[str, str | None, int]]:
    """(imported module, imported name or None, line) of every torquemod import in
    ``name``, relative ones resolved."""
    tree = ast.parse(MODULES[name].read_text(encoding="utf-8"))
    package = name if _is_package(name) else name.rsplit(".", 1)[0]
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [(a.name, None, node.lineno) for a in node.names
                    if a.name.split(".")[0] == "torquemod"]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[:len(package.split(".")) - node.level + 1]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            if mod.split(".")[0] != "torquemod":
                continue
            for a in node.names:
                full = f"{mod}.{a.name}"
                out.append((full, None, node.lineno) if full in MODULES
                           else (mod, a.name, node.lineno))
    return out


def _owner(module: str) -> str:
    """The module itself if it exists, else its longest existing parent."""
    parts = module.split(".")
    while ".".join(parts) not in MODULES:
        parts.pop()
    return ".".join(parts)


def test_import_contracts():
    """``lint-imports`` (import-linter) keeps every contract of pyproject.toml."""
    exe = Path(sys.executable).with_name("lint-imports")
    cmd = [str(exe)] if exe.exists() else [sys.executable, "-m", "importlinter.cli"]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        [str(SRC), *filter(None, [os.environ.get("PYTHONPATH")])])}
    got = subprocess.run([*cmd, "--no-cache"], cwd=ROOT, env=env, capture_output=True,
                         text=True, timeout=300)
    assert got.returncode == 0, got.stdout[-4000:] + got.stderr[-2000:]


def _graph(level_of) -> dict[str, set[str]]:
    edges: dict[str, set[str]] = {}
    for name in MODULES:
        a = level_of(name)
        if a is None:
            continue
        for mod, _, _ in _imports(name):
            b = level_of(_owner(mod))
            if b is not None and b != a:
                edges.setdefault(a, set()).add(b)
    return edges


def _cycle(edges: dict[str, set[str]]) -> list[str] | None:
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(n: str) -> list[str] | None:
        state[n] = 1
        stack.append(n)
        for m in sorted(edges.get(n, ())):
            if state.get(m) == 1:
                return [*stack[stack.index(m):], m]
            if m not in state and (found := visit(m)):
                return found
        stack.pop()
        state[n] = 2
        return None

    for n in sorted(edges):
        if n not in state and (found := visit(n)):
            return found
    return None


PACKAGES = sorted(n for n in MODULES if _is_package(n))


@pytest.mark.parametrize("package", PACKAGES)
def test_no_import_cycle_inside_a_package(package):
    """Between the children (modules and subpackages) of ``package``, imports form no
    cycle; a package's ``__init__`` re-exporting its children is not a cycle."""
    depth = package.count(".") + 1

    def child(name: str) -> str | None:
        if name == package or not name.startswith(package + "."):
            return None
        return ".".join(name.split(".")[:depth + 1])

    cycle = _cycle(_graph(child))
    assert cycle is None, " -> ".join(cycle)


def test_no_private_name_imported_from_another_package():
    """A name starting with ``_`` is imported only inside the package that holds it
    (``_util`` and ``_cli`` are private to torquemod itself)."""
    bad = []
    for name in MODULES:
        importer_pkg = name if _is_package(name) else name.rsplit(".", 1)[0]
        for mod, attr, line in _imports(name):
            parts = mod.split(".") + ([attr] if attr else [])
            for k, part in enumerate(parts):
                if not part.startswith("_") or part.startswith("__") or k == 0:
                    continue
                holder = ".".join(parts[:k])
                scope = holder if holder in MODULES and _is_package(holder) else \
                    holder.rsplit(".", 1)[0]
                if not (importer_pkg == scope or importer_pkg.startswith(scope + ".")):
                    bad.append(f"{name}:{line} imports {'.'.join(parts)}")
                    break
    assert not bad, "\n".join(bad)


def test_no_module_hides_a_public_name():
    """Importing a subpackage makes it an attribute of ``torquemod``: no subpackage or module
    may carry the name of a public call (``tm.process`` stays the function after
    ``import torquemod.processing``); ``tm.twin`` is the twin's facade module on purpose."""
    import importlib

    for name in MODULES:
        importlib.import_module(name)
    hidden = [n for n in torquemod.__all__ if n != "twin"
              and type(getattr(torquemod, n)).__name__ == "module"]
    assert not hidden, hidden
