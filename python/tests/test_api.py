"""The package used as a user would: create, bulk-load from numpy, look up
by key, query, change, and maintain, with answers checked against brute
force on a grid of tetrahedra."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import mktree
from conftest import grid, tetra


def test_bulk_load_from_numpy_then_every_query_kind(make_db) -> None:
    objects = grid(5)
    db = make_db(objects)
    info = db.stats()
    assert info is not None and info.objects == 125 and info.triangles == 500
    with db.read() as r:
        assert len(r) == 125
        # The box holds tetrahedra (0,0,0) .. (1,1,1) of the grid: 2000 mm spacing.
        a = r.box((0, 0, 0), (2500, 2500, 2500))
        assert sorted(a.keys) == [0, 1, 5, 6, 25, 26, 30, 31]
        assert a.keys == list(a) and len(a) == 8 and a[0] == a.keys[0] and a[-1] == a.keys[-1]
        assert a.ids.dtype == np.uint32 and list(a.ids) == sorted(a.ids)
        assert a.key_array().dtype == np.uint64 and list(a.key_array()) == a.keys
        assert 31 in a and 32 not in a
        assert a.stats.block_reads + a.stats.cache_hits > 0 and a.level == 4
        # The ball about a tetrahedron's corner reaches no other.
        assert r.sphere((4000, 4000, 4000), 500).keys == [(2 * 5 + 2) * 5 + 2]
        # Looking along +x at the grid's first row.
        f = r.frustum((-20000, 500, 500), (0, 500, 500), 2.0, 1.0, 1.0, 30000.0)
        assert sorted(f.keys) == [0, 25, 50, 75, 100]
        near = r.nearest((-100, 0, 0), 3)
        assert [n.key for n in near][0] == 0 and near[0].distance == pytest.approx(100.0)
        assert near[0].distance <= near[1].distance <= near[2].distance
        hits = r.ray((-1000, 100, 100), (1, 0, 0))
        assert [h.key for h in hits] == [0, 25, 50, 75, 100]
        assert hits[0].t == pytest.approx(1000.0) and hits[0].point[0] == pytest.approx(0.0, abs=1e-9)
        assert [h.key for h in r.ray((-1000, 100, 100), (1, 0, 0), k=2)] == [0, 25]
        assert [h.key for h in r.ray((-1000, 100, 100), (1, 0, 0), max_distance=3500.0)] == [0, 25]


def test_collide_and_clearance_with_a_pose_a_matrix_a_key(make_db) -> None:
    db = make_db(grid(3))
    probe = tetra((0, 0, 0), 100.0)
    with db.read() as r:
        assert r.collide(probe).keys == [0]
        # Moved to touch nothing, then within 600 mm of tetrahedron 0's far corner.
        moved = mktree.Pose((1500, 1500, 1500))
        assert r.collide(probe, moved).keys == []
        assert r.clearance(probe, 2000.0, moved).keys != []
        matrix = np.eye(4)
        matrix[:3, 3] = (2000, 0, 0)
        assert r.collide(probe, matrix).keys == [9]
        assert r.collide(probe, (2000.0, 0.0, 0.0)).keys == [9]
        # A stored object by key is left out of its own answer.
        assert r.collide(0).keys == []
        assert r.collide(0, clearance=1100.0).keys == [1, 3, 9]
        # Lazily.
        assert sorted(h.key for h in r.iter_collide(probe)) == [0]


def test_clash_gives_key_pairs_and_id_arrays(make_db) -> None:
    objects = grid(2)
    # Object 7 is moved onto object 0: they clash.
    m = tetra((500, 0, 0))
    objects[7] = mktree.Object("moved", m.vertices, m.triangles)
    db = make_db(objects)
    with db.read() as r:
        c = r.clash()
        assert c.pairs == [(0, "moved")] and len(c) == 1 and list(c) == c.pairs
        assert c.id_pairs.shape == (1, 2) and c.id_pairs.tolist() == [[0, 7]]
        assert r.clash(clearance=1500.0).pairs != []


def test_lazy_iteration_reads_only_what_it_needs(make_db) -> None:
    db = make_db(grid(6), block_size=1024)
    with db.read() as r:
        everything = r.box((-1, -1, -1), (20000, 20000, 20000), cache=False)
        it = r.iter_box((-1, -1, -1), (20000, 20000, 20000), cache=False)
        first = next(it)
        assert first.key in everything and first.proof in ("inside_node", "face", "cell", "exact")
        assert 0 < it.stats.block_reads < everything.stats.block_reads
        rest = list(it)
        assert sorted([first.key] + [h.key for h in rest]) == sorted(everything.keys)
        nearest = r.iter_nearest((0, 0, 0))
        assert next(nearest).key == 0
        assert [h.key for h in r.iter_ray((-1000, 100, 100), (1, 0, 0))][:2] == [0, 36]


def test_get_mesh_object_and_payloads(make_db) -> None:
    objects = grid(2)
    objects[3] = objects[3]._replace(key="pump P-101", payload=b"\x00raw")
    db = make_db(objects)
    with db.read() as r:
        rec = r.get(5)
        assert rec is not None and rec.json() == {"i": 1, "j": 0, "k": 1} and rec.id == 5
        assert rec.bounds == pytest.approx((2000, 0, 2000, 3000, 1000, 3000))
        assert r["pump P-101"].payload == b"\x00raw"
        assert "pump P-101" in r and "nothing" not in r and r.get(99) is None
        with pytest.raises(mktree.KeyNotFoundError) as e:
            r[99]
        assert isinstance(e.value, KeyError) and "99" in str(e.value)
        mesh = r.mesh(5)
        assert mesh is not None
        np.testing.assert_allclose(mesh.vertices, objects[5].vertices)
        np.testing.assert_array_equal(mesh.triangles, objects[5].triangles)
        o = r.object(5)
        assert o is not None and o.key == 5 and o.name == "t5" and o.payload == b'{"i":1,"j":0,"k":1}'


def test_changes_commit_together_and_an_exception_aborts(make_db) -> None:
    db = make_db(grid(2))
    m = tetra((10000, 0, 0))
    with db.write() as w:
        assert w.insert(mktree.Object(None, m.vertices, m.triangles)) == 8  # the next integer key
        w.insert(("pipe", m.vertices + 3000, m.triangles, {"class": "IfcPipeSegment"}))
        w.update(mktree.Object(0, m.vertices, m.triangles, b"moved"))
        assert w.remove(1) is True and w.remove(1, missing_ok=True) is False
        w.move_by(2, (0, 0, 50000))
        got = w.get(0)
        assert got is not None and got.payload == b"moved"
    with db.read() as r:
        assert len(r) == 9 and 1 not in r and r["pipe"].json() == {"class": "IfcPipeSegment"}
        assert r.box((9999, -1, -1), (11001, 1001, 1001)).keys == [0, 8]
        assert r[2].bounds[2] == pytest.approx(50000)
    # An exception in the block aborts: nothing of it is committed.
    with pytest.raises(RuntimeError):
        with db.write() as w:
            w.remove(0)
            raise RuntimeError("stop")
    with db.read() as r:
        assert 0 in r
    # Explicit commit returns what it wrote; the transaction is then closed.
    w = db.write()
    w.remove(0)
    stats = w.commit()
    assert stats.changes == 1 and stats.blocks_written > 0 and w.closed
    with pytest.raises(mktree.ClosedError):
        w.remove(3)
    w = db.write()
    w.remove(3)
    w.abort()
    with db.read() as r:
        assert 3 in r and 0 not in r


def test_a_thread_with_an_open_write_transaction_cannot_begin_another(make_db) -> None:
    db = make_db(grid(2))
    w = db.write()
    with pytest.raises(mktree.Error, match="this thread's write transaction is still open"):
        db.write()
    w.abort()
    with db.write() as w2:
        w2.remove(0)
    w3 = db.write()
    del w3  # dropped unended: aborted, and the thread may write again
    with db.write() as w4:
        w4.remove(1)
    assert len(db.read()) == 6


def test_a_snapshot_does_not_see_later_commits(make_db) -> None:
    db = make_db(grid(2))
    r = db.read()
    with db.write() as w:
        w.remove(0)
    assert 0 in r and 0 not in db.read()
    r.close()
    assert r.closed
    with pytest.raises(mktree.ClosedError):
        r.box((0, 0, 0), (1, 1, 1))


def test_stats_check_compact_and_reopen(make_db, tmp_path: Path) -> None:
    db = make_db(grid(4))
    assert db.block_size == 16384 and db.lod_levels == 4 and not db.read_only
    for _ in range(3):
        with db.write() as w:
            w.bulk_load(grid(4))
    before = db.stats()
    assert before is not None and before.free_blocks > 0
    report = db.check()
    assert report.ok and bool(report) and report.objects == 64 and report.faults == []
    c = db.compact()
    assert c.blocks_after < c.blocks_before
    db.close()
    assert db.closed
    with mktree.open(tmp_path / "t.mkt", read_only=True) as ro:
        assert ro.read_only and len(ro.read()) == 64 and ro.check().ok
        with pytest.raises(mktree.ReadOnlyError):
            ro.write()


def test_generated_and_imported_scenes_load(make_db, tmp_path: Path, cli: str) -> None:
    import subprocess

    scene = mktree.generate("tanker1")
    assert len(scene) == 222 and scene[0].key == 0 and scene[0].vertices.shape[1] == 3
    obj = tmp_path / "t1.obj"
    subprocess.run([cli, "gen", "tanker1", "-o", str(obj)], check=True, capture_output=True)
    imported = mktree.read_scene(obj)
    assert len(imported) == 222
    db = make_db(imported)
    assert db.stats().objects == 222  # type: ignore[union-attr]
