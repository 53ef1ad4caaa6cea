"""Errors are Python exceptions with the engine's message; malformed arrays
raise ValueError before anything is written (the file keeps its commit)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import mktree
from conftest import grid, tetra

GOOD = tetra()


def txn_of(db: mktree.Database) -> int:
    info = db.stats()
    return -1 if info is None else info.txn


@pytest.mark.parametrize(
    "vertices, triangles, message",
    [
        (GOOD.vertices[:, :2], GOOD.triangles, r"vertices must be an array of shape \(n, 3\), not \(4, 2\)"),
        (GOOD.vertices.ravel(), GOOD.triangles, r"vertices must be an array of shape \(n, 3\), not \(12,\)"),
        (GOOD.vertices.astype(complex), GOOD.triangles, "vertices must be a float64 array"),
        (GOOD.vertices.astype(str), GOOD.triangles, "vertices must be a float64 array"),
        (np.where(np.arange(12).reshape(4, 3) == 4, np.nan, GOOD.vertices), GOOD.triangles, "vertex 1 has a non-finite"),
        (np.where(np.arange(12).reshape(4, 3) == 0, np.inf, GOOD.vertices), GOOD.triangles, "vertex 0 has a non-finite"),
        (GOOD.vertices, GOOD.triangles.astype(np.float64), "triangles must be an integer array"),
        (GOOD.vertices, GOOD.triangles[:, :2], r"triangles must be an array of shape \(n, 3\)"),
        (GOOD.vertices, GOOD.triangles + 1, "triangle 1 uses vertex index 4, but the object has 4 vertices"),
        (GOOD.vertices, GOOD.triangles - 1, "uses vertex index -1"),
        (GOOD.vertices, np.zeros((0, 3), np.int32), "object has no triangles"),
        ([[0, 0, 0], [1, 0]], GOOD.triangles, "vertices"),
    ],
)
def test_a_malformed_array_raises_value_error_and_writes_nothing(make_db, vertices, triangles, message) -> None:
    db = make_db(grid(2))
    before = txn_of(db)
    objects = grid(2) + [mktree.Object("bad", vertices, triangles)]
    with pytest.raises(ValueError, match=message):
        with db.write() as w:
            w.bulk_load(objects)
    assert txn_of(db) == before and db.check().ok
    with pytest.raises(ValueError, match=message):
        with db.write() as w:
            w.insert(mktree.Object("bad", vertices, triangles))
    with pytest.raises(ValueError, match=message):
        db.read().collide((vertices, triangles))
    assert txn_of(db) == before and len(db.read()) == 8


def test_the_failing_object_is_named(make_db) -> None:
    db = make_db()
    objects = grid(2)
    objects[5] = objects[5]._replace(triangles=objects[5].triangles + 10)
    with pytest.raises(ValueError, match="^object 5: triangle 0 uses vertex index 10"):
        with db.write() as w:
            w.bulk_load(objects)
    assert db.stats() is None


def test_other_array_types_are_converted(make_db) -> None:
    db = make_db()
    with db.write() as w:
        w.bulk_load(
            [
                (0, GOOD.vertices.astype(np.float32), GOOD.triangles.astype(np.uint16)),
                (1, GOOD.vertices.astype(np.int64) + 5000, GOOD.triangles.astype(np.uint32)),
                (2, (GOOD.vertices + 10000).tolist(), GOOD.triangles.tolist()),
                (3, np.asfortranarray(GOOD.vertices + 15000), GOOD.triangles[:, ::-1]),
            ]
        )
    assert sorted(db.read().box((-1, -1, -1), (1e6, 1e6, 1e6)).keys) == [0, 1, 2, 3]


def test_keys_and_payloads_are_checked(make_db) -> None:
    db = make_db()
    v, t = GOOD
    for key, error, message in [
        (-1, ValueError, "an integer key lies in 0"),
        (2**64, ValueError, "an integer key lies in 0"),
        ("x" * 256, ValueError, "a key of 256 bytes"),
        (1.5, TypeError, "a key is an int, a str or bytes"),
        (True, TypeError, "a key is an int"),
    ]:
        with pytest.raises(error, match=message):
            with db.write() as w:
                w.bulk_load([(key, v, t)])
    with pytest.raises(ValueError, match="a payload of 1025 bytes"):
        with db.write() as w:
            w.bulk_load([(0, v, t, b"x" * 1025)])
    with pytest.raises(TypeError, match="a payload is bytes or a dict"):
        with db.write() as w:
            w.bulk_load([(0, v, t, 5)])
    with pytest.raises(mktree.DuplicateKeyError, match="share the key 7"):
        with db.write() as w:
            w.bulk_load([(7, v, t), (7, v + 5000, t)])
    assert db.stats() is None
    with db.write() as w:
        w.bulk_load([(np.uint16(7), v, t)])  # numpy integers are integer keys
    with pytest.raises(mktree.DuplicateKeyError, match="already in the tree") as e:
        with db.write() as w:
            w.insert((7, v, t))
    assert isinstance(e.value, ValueError) and isinstance(e.value, mktree.Error)
    with pytest.raises(mktree.KeyNotFoundError, match="no object has key 8"):
        with db.write() as w:
            w.remove(8)
    with pytest.raises(mktree.KeyNotFoundError):
        with db.write() as w:
            w.move_by(8, (1, 2, 3))


def test_queries_refuse_bad_numbers(make_db) -> None:
    r = make_db(grid(2)).read()
    with pytest.raises(ValueError, match="level 9 is not one of the file's levels 1..=4"):
        r.box((0, 0, 0), (1, 1, 1), lod=9)
    with pytest.raises(ValueError, match="radius"):
        r.sphere((0, 0, 0), -1.0)
    with pytest.raises(ValueError, match="outside the coordinate range"):
        r.box((0, 0, 0), (1e300, 1, 1))
    with pytest.raises(ValueError, match="is 3 numbers"):
        r.box((0, 0), (1, 1, 1))
    with pytest.raises(ValueError, match="clearance"):
        r.collide(GOOD, clearance=-1.0)
    with pytest.raises(ValueError, match="affine"):
        r.collide(GOOD, np.ones((4, 4)))
    with pytest.raises(ValueError):
        r.ray((0, 0, 0), (0, 0, 0))
    with pytest.raises(mktree.KeyNotFoundError):
        r.collide("no such key")


def test_files_and_processes(tmp_path: Path, make_db) -> None:
    with pytest.raises(FileNotFoundError, match="cannot open"):
        mktree.open(tmp_path / "missing.mkt")
    make_db(grid(2), name="there.mkt")
    with pytest.raises(FileExistsError):
        mktree.create(tmp_path / "there.mkt")
    with pytest.raises(ValueError, match="invalid block size 1000"):
        mktree.create(tmp_path / "new.mkt", block_size=1000)
    (tmp_path / "text.mkt").write_bytes(b"hello, not an index" * 100)
    with pytest.raises(mktree.CorruptionError, match="not an MKtree file"):
        mktree.open(tmp_path / "text.mkt")
    # Another process holds the write transaction: LockedError here, with the engine's message.
    holder = subprocess.Popen(
        [sys.executable, "-c",
         "import mktree, sys; db = mktree.open(sys.argv[1]); w = db.write(); print('ready', flush=True); sys.stdin.read()",
         str(tmp_path / "there.mkt")],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=dict(os.environ),
    )
    try:
        assert holder.stdout is not None and holder.stdout.readline().strip() == "ready"
        db = mktree.open(tmp_path / "there.mkt")
        with pytest.raises(mktree.LockedError, match="another process is writing the file"):
            db.write()
        assert len(db.read()) == 8  # readers never wait
    finally:
        holder.communicate("")
    with mktree.open(tmp_path / "there.mkt").write() as w:
        w.remove(0)
