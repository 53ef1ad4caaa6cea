"""Every public name has a type and a docstring: the stub of the extension
module matches it at runtime (mypy's stubtest), documents every class,
method and property, and a type checker passes on the examples, the
benchmarks and the package (mypy --strict, pyproject.toml)."""

from __future__ import annotations

import ast
import inspect
import subprocess
import sys
from pathlib import Path
from typing import Dict

import mktree
from mktree import _mktree

PACKAGE = Path(mktree.__file__).resolve().parent
PROJECT = Path(__file__).resolve().parent.parent


def stub_defs() -> Dict[str, ast.AST]:
    tree = ast.parse((PACKAGE / "_mktree.pyi").read_text())
    return {n.name: n for n in tree.body if isinstance(n, (ast.ClassDef, ast.FunctionDef))}


def test_the_stub_documents_every_class_method_and_property() -> None:
    defs = stub_defs()
    for name in _mktree.__all__:
        assert name in defs, f"{name} is not in _mktree.pyi"
        node = defs[name]
        assert ast.get_docstring(node), f"{name} has no docstring in the stub"
        if isinstance(node, ast.ClassDef):
            members = {m.name: m for m in node.body if isinstance(m, ast.FunctionDef)}
            runtime = getattr(_mktree, name)
            for attr in dir(runtime):
                if attr.startswith("_"):
                    continue
                assert attr in members, f"{name}.{attr} is not in the stub"
                assert ast.get_docstring(members[attr]), f"{name}.{attr} has no docstring in the stub"


def test_every_public_name_of_the_package_has_a_docstring() -> None:
    aliases = {}
    for module in ("_types.py", "__init__.py"):
        body = ast.parse((PACKAGE / module).read_text()).body
        for a, b in zip(body, body[1:]):
            if isinstance(a, ast.Assign) and isinstance(b, ast.Expr) and isinstance(b.value, ast.Constant):
                for t in a.targets:
                    if isinstance(t, ast.Name):
                        aliases[t.id] = b.value.value
    defs = stub_defs()
    for name in mktree.__all__:
        if name in defs:
            continue
        obj = getattr(mktree, name)
        doc = aliases.get(name) or (inspect.getdoc(obj) if inspect.isclass(obj) or callable(obj) else None)
        assert doc and doc.strip(), f"mktree.{name} has no docstring"
    for module in ("ifc",):
        m = __import__(f"mktree.{module}", fromlist=["_"])
        for name in m.__all__:
            assert inspect.getdoc(getattr(m, name)), f"mktree.{module}.{name} has no docstring"


def test_stubtest_finds_the_stub_true_to_the_module() -> None:
    run = subprocess.run([sys.executable, "-m", "mypy.stubtest", "mktree._mktree"],
                         capture_output=True, text=True, cwd=PROJECT / "tests")
    assert run.returncode == 0, run.stdout + run.stderr


def test_mypy_strict_passes_on_the_examples_and_the_package() -> None:
    run = subprocess.run([sys.executable, "-m", "mypy"], capture_output=True, text=True, cwd=PROJECT)
    assert run.returncode == 0, run.stdout + run.stderr
