"""Shared fixtures: a scratch folder, small meshes, the ``mktree`` binary."""

from __future__ import annotations

import os
import shutil
import sys
from pathlib import Path
from typing import Callable, List

import numpy as np
import pytest

import mktree

HERE = Path(__file__).resolve().parent
REPO = HERE.parent.parent
sys.path.insert(0, str(HERE.parent / "examples"))


def tetra(at: "tuple[float, float, float]" = (0.0, 0.0, 0.0), size: float = 1000.0) -> mktree.Mesh:
    """A tetrahedron with its right-angle corner at ``at``."""
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=np.float64) * size + np.asarray(at)
    t = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]], dtype=np.int64)
    return mktree.Mesh(v, t)


def grid(n: int = 5, spacing: float = 2000.0) -> List[mktree.Object]:
    """n**3 tetrahedra 1 m across on a grid, keyed 0 .. n**3 - 1."""
    objects = []
    for i in range(n):
        for j in range(n):
            for k in range(n):
                m = tetra((i * spacing, j * spacing, k * spacing))
                key = (i * n + j) * n + k
                objects.append(mktree.Object(key, m.vertices, m.triangles, {"i": i, "j": j, "k": k}, f"t{key}"))
    return objects


@pytest.fixture
def make_db(tmp_path: Path) -> Callable[..., mktree.Database]:
    """A new database at tmp_path, bulk-loaded with ``objects`` when given."""

    def make(objects: "List[mktree.Object] | None" = None, name: str = "t.mkt", **kw: int) -> mktree.Database:
        db = mktree.Database.create(tmp_path / name, **kw)
        if objects is not None:
            with db.write() as w:
                w.bulk_load(objects)
        return db

    return make


def find_cli() -> "str | None":
    """The mktree binary: $MKTREE_CLI, else the workspace's release build."""
    named = os.environ.get("MKTREE_CLI")
    if named:
        assert os.path.exists(named), f"MKTREE_CLI={named} does not exist"
        return named
    for target in [os.environ.get("CARGO_TARGET_DIR"), str(REPO / "target")]:
        if target and os.path.exists(os.path.join(target, "release", "mktree")):
            return os.path.join(target, "release", "mktree")
    return shutil.which("mktree")


@pytest.fixture(scope="session")
def cli() -> str:
    """The mktree binary; CI names it in MKTREE_CLI, so there it is never skipped."""
    found = find_cli()
    if found is None:
        pytest.skip("no mktree binary: cargo build --release, or set MKTREE_CLI")
    return found
