"""trimesh in and out: a scene's nodes become objects in world
coordinates keyed by node name, and an answer comes back as a scene."""

from __future__ import annotations

import numpy as np
import trimesh

import mktree


def test_a_trimesh_scene_round_trips(make_db) -> None:
    scene = trimesh.Scene()
    box = trimesh.creation.box(extents=(1000, 1000, 1000))
    for i in range(4):
        scene.add_geometry(box, node_name=f"box{i}", geom_name="box",
                           transform=trimesh.transformations.translation_matrix((3000 * i, 0, 0)))
    objects = mktree.from_trimesh(scene)
    assert sorted(o.key for o in objects) == ["box0", "box1", "box2", "box3"]
    db = make_db(objects)
    with db.read() as r:
        hits = r.box((2400, -600, -600), (3600, 600, 600))
        assert hits.keys == ["box1"]
        back = mktree.to_trimesh(r, hits)
        assert list(back.geometry) == ["box1"]
        np.testing.assert_allclose(back.bounds, [[2500, -500, -500], [3500, 500, 500]])
        # A trimesh as the query mesh, placed by a 4x4 matrix.
        probe = trimesh.creation.icosphere(radius=200.0)
        assert r.collide(probe, trimesh.transformations.translation_matrix((6000, 0, 600))).keys == ["box2"]
        # Surfaces meet, not volumes: inside box0, the sphere touches nothing; across its face, box0.
        assert r.collide(probe).keys == []
        assert r.collide(probe, (500.0, 0.0, 0.0)).keys == ["box0"]


def test_one_trimesh_is_one_object(make_db) -> None:
    mesh = trimesh.creation.cylinder(radius=50.0, height=2000.0)
    (o,) = mktree.from_trimesh(mesh, key=42)
    assert o.key == 42 and o.vertices.shape == mesh.vertices.shape
    db = make_db([o])
    assert db.read().nearest((0, 0, 2000))[0].key == 42
