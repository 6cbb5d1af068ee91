"""Every public function and class of the documented packages carries a numpydoc docstring:
a summary line, a ``Parameters`` section naming every parameter, a ``Returns`` (or
``Yields``) section when it returns a value, a units bracket (``[m/s]``, ``[-]``, ...) for
every parameter documented as a float, and for a dataclass every field described (in an
``Attributes`` section or a docstring under the field) with units when it is a float.

Run as a script (``python tests/test_numpydoc.py [package ...]``) it prints the count of
public callables that pass and every problem found.
"""

from __future__ import annotations

import ast
import dataclasses
import importlib
import inspect
import itertools
import pkgutil
import re
import sys
import textwrap

import pytest

# the whole package: every public function and class of every public module (private
# packages and modules, with a leading underscore, are left out)
DOCUMENTED = ("torquemod",)

_SECTION = re.compile(r"^\s*([A-Z][A-Za-z ]+)\n\s*-{3,}\s*$", re.MULTILINE)
_ENTRY = re.compile(r"^(\*{0,2}[A-Za-z_][\w]*(?:\s*,\s*\*{0,2}[A-Za-z_]\w*)*)\s*(?::\s*(.*))?$")
_UNITS = re.compile(r"\[[^\]]+\]")


def _sections(doc: str) -> dict[str, str]:
    """The docstring's numpydoc sections, by title, each with its body (dedented)."""
    doc = inspect.cleandoc(doc)
    found = list(_SECTION.finditer(doc))
    out = {"": doc[:found[0].start()] if found else doc}
    for k, m in enumerate(found):
        end = found[k + 1].start() if k + 1 < len(found) else len(doc)
        out[m.group(1).strip()] = textwrap.dedent(doc[m.end():end]).strip("\n")
    return out


def _entries(body: str) -> dict[str, tuple[str, str]]:
    """The entries of a Parameters/Attributes section: name -> (type, description)."""
    out: dict[str, tuple[str, str]] = {}
    names: list[str] = []
    typ = ""
    desc: list[str] = []

    def flush():
        for n in names:
            out[n.lstrip("*")] = (typ, " ".join(desc))

    for line in body.splitlines():
        if line and not line[0].isspace():
            m = _ENTRY.match(line.strip())
            if m:
                flush()
                names = [n.strip() for n in m.group(1).split(",")]
                typ = (m.group(2) or "").strip()
                desc = []
                continue
        desc.append(line.strip())
    flush()
    return out


def _is_float(typ: str) -> bool:
    """Whether a documented type is a real number (so it needs units)."""
    return bool(re.match(r"^(float|ndarray of float|array_like of float)\b", typ))


def _returns_value(func) -> bool:
    """Whether the function has a ``return <value>`` of its own (not in nested functions)."""
    try:
        src = textwrap.dedent(inspect.getsource(func))
        tree = ast.parse(src)
    except (OSError, TypeError, SyntaxError):
        return False
    top = tree.body[0]
    if isinstance(top, ast.AsyncFunctionDef | ast.FunctionDef):
        ann = top.returns
        if ann is not None and ast.unparse(ann) in ("None", "NoReturn"):
            return False
        if ann is not None and ast.unparse(ann).startswith(("Iterator", "Generator")):
            return True

    def walk(node):
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef | ast.Lambda
                          | ast.ClassDef):
                continue
            if isinstance(child, ast.Return) and child.value is not None and not (
                    isinstance(child.value, ast.Constant) and child.value.value is None):
                return True
            if isinstance(child, ast.Yield | ast.YieldFrom):
                return True
            if walk(child):
                return True
        return False

    return walk(top)


def _parameters(func) -> list[inspect.Parameter]:
    try:
        sig = inspect.signature(func)
    except (TypeError, ValueError):
        return []
    return [p for p in sig.parameters.values() if p.name not in ("self", "cls")]


def check_function(func, where: str, doc: str | None = None) -> list[str]:
    """The numpydoc problems of one function (``doc`` overrides its own docstring)."""
    doc = doc if doc is not None else inspect.getdoc(func)
    if not doc or not doc.strip():
        return [f"{where}: no docstring"]
    problems = []
    sec = _sections(doc)
    if not sec[""].strip():
        problems.append(f"{where}: no summary line")
    params = _parameters(func)
    if params:
        if "Parameters" not in sec:
            problems.append(f"{where}: no Parameters section "
                            f"({', '.join(p.name for p in params)})")
        else:
            entries = _entries(sec["Parameters"])
            for p in params:
                if p.name not in entries:
                    problems.append(f"{where}: parameter {p.name!r} not documented")
                    continue
                typ, desc = entries[p.name]
                if _is_float(typ) and not _UNITS.search(desc):
                    problems.append(f"{where}: float parameter {p.name!r} has no [units]")
    if _returns_value(func) and "Returns" not in sec and "Yields" not in sec:
        problems.append(f"{where}: returns a value but has no Returns section")
    return problems


def _field_docstrings(cls) -> dict[str, str]:
    """Docstrings written as a string literal right under a class-level field."""
    try:
        tree = ast.parse(textwrap.dedent(inspect.getsource(cls)))
    except (OSError, TypeError, SyntaxError):
        return {}
    body = tree.body[0].body
    out = {}
    for a, b in itertools.pairwise(body):
        if (isinstance(a, ast.AnnAssign) and isinstance(a.target, ast.Name)
                and isinstance(b, ast.Expr) and isinstance(b.value, ast.Constant)
                and isinstance(b.value.value, str)):
            out[a.target.id] = b.value.value
    return out


def check_class(cls, where: str) -> list[str]:
    """The numpydoc problems of one class: its docstring, its fields or constructor."""
    doc = cls.__doc__  # not inspect.getdoc: a dataclass's generated doc is not documentation
    if not doc or not doc.strip() or (dataclasses.is_dataclass(cls)
                                      and doc.startswith(cls.__name__ + "(")):
        return [f"{where}: no docstring"]
    problems = []
    sec = _sections(doc)
    if not sec[""].strip():
        problems.append(f"{where}: no summary line")
    if dataclasses.is_dataclass(cls):
        entries = {}
        for title in ("Attributes", "Parameters"):
            entries.update(_entries(sec.get(title, "")))
        own = _field_docstrings(cls)
        for f in dataclasses.fields(cls):
            if f.name.startswith("_"):
                continue
            if f.name in own:
                ann = f.type if isinstance(f.type, str) else getattr(f.type, "__name__", "")
                if ann.startswith("float") and not _UNITS.search(own[f.name]):
                    problems.append(f"{where}: float field {f.name!r} has no [units]")
                continue
            if f.name not in entries:
                problems.append(f"{where}: field {f.name!r} not documented")
                continue
            typ, desc = entries[f.name]
            if _is_float(typ) and not _UNITS.search(desc):
                problems.append(f"{where}: float field {f.name!r} has no [units]")
    elif issubclass(cls, BaseException):
        pass
    elif "__init__" in cls.__dict__ and _parameters(cls.__init__):
        init_doc = inspect.getdoc(cls.__init__) if cls.__init__.__doc__ else None
        if init_doc and "Parameters" in _sections(init_doc):
            problems += check_function(cls.__init__, where + ".__init__", init_doc)
        else:
            problems += check_function(cls.__init__, where, doc)
    return problems


def public_callables(packages=DOCUMENTED):
    """(qualified name, object) of every public function and class defined in ``packages``."""
    seen = set()
    for top in packages:
        mod = importlib.import_module(top)
        names = [top]
        if hasattr(mod, "__path__"):
            names += [m.name for m in pkgutil.walk_packages(mod.__path__, top + ".")]
        for name in names:
            if any(part.startswith("_") for part in name.split(".")[1:]):
                continue
            module = importlib.import_module(name)
            for attr, obj in sorted(vars(module).items()):
                if attr.startswith("_") or not (inspect.isfunction(obj) or inspect.isclass(obj)):
                    continue
                if getattr(obj, "__module__", None) != name or id(obj) in seen:
                    continue
                seen.add(id(obj))
                yield f"{name}.{attr}", obj


def problems_of(qualname: str, obj) -> list[str]:
    if inspect.isclass(obj):
        return check_class(obj, qualname)
    return check_function(obj, qualname)


def test_parser_sees_a_missing_unit_and_a_missing_parameter():
    """The check can fail: a float parameter without units and an undocumented one."""
    def bad(speed_m_s: float, n: int):
        """Summary.

        Parameters
        ----------
        speed_m_s : float
            Speed.

        Returns
        -------
        float
            Something [-].
        """
        return speed_m_s * n

    found = check_function(bad, "bad")
    assert any("'speed_m_s' has no [units]" in p for p in found)
    assert any("'n' not documented" in p for p in found)

    @dataclasses.dataclass
    class Bad:
        """Summary.

        Attributes
        ----------
        mu : float
            Friction.
        """

        mu: float
        k: int

    found = check_class(Bad, "Bad")
    assert any("'mu' has no [units]" in p for p in found)
    assert any("'k' not documented" in p for p in found)


ALL = list(public_callables())


@pytest.mark.parametrize("module", sorted({q.rsplit(".", 1)[0] for q, _ in ALL}))
def test_public_callables_have_numpydoc(module):
    problems = [p for q, obj in ALL if q.rsplit(".", 1)[0] == module
                for p in problems_of(q, obj)]
    assert not problems, "\n".join(problems)


if __name__ == "__main__":
    pkgs = tuple(sys.argv[1:]) or DOCUMENTED
    good = bad = 0
    for q, obj in public_callables(pkgs):
        found = problems_of(q, obj)
        if found:
            bad += 1
            print("\n".join(found))
        else:
            good += 1
    print(f"{good} of {good + bad} public functions/classes have full numpydoc")
