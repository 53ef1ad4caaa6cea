"""The IFC loader on a model made with ``ifcopenshell.api`` (walls, slabs,
pipes, ducts; 2,184 elements): its keys are exactly the model's GlobalIds,
as IfcOpenShell lists them, each with its class and name; it runs from the
command line; the example script reports clashes and draws its chart."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import ifcopenshell
import pytest

import mktree
import mktree.ifc
from conftest import HERE
from ifc_plant import make_plant


@pytest.fixture(scope="module")
def plant(tmp_path_factory: pytest.TempPathFactory) -> "tuple[Any, Path]":
    d = tmp_path_factory.mktemp("ifc")
    model = make_plant(12)
    path = d / "plant.ifc"
    model.write(str(path))
    return model, path


def test_the_loader_indexes_every_element_by_its_global_id(plant: "tuple[Any, Path]", tmp_path: Path) -> None:
    model, path = plant
    elements = model.by_type("IfcElement")
    assert len(elements) >= 2000
    out = tmp_path / "plant.mkt"
    run = subprocess.run([sys.executable, "-m", "mktree.ifc", str(path), "-o", str(out)],
                         capture_output=True, text=True, check=True)
    assert f"{len(elements)} elements" in run.stdout
    with mktree.open(out, read_only=True) as db:
        r = db.read()
        everything = r.box((-1e6, -1e6, -1e6), (1e6, 1e6, 1e6))
        assert sorted(everything.keys) == sorted(e.GlobalId for e in elements)
        for e in elements[::97]:
            assert r[e.GlobalId].json() == {"class": e.is_a(), "name": e.Name}
        classes = {r[k].json()["class"] for k in everything.keys[::5]}
        assert {"IfcWall", "IfcSlab", "IfcPipeSegment", "IfcDuctSegment"} <= classes
        assert db.check().ok


def test_geometry_is_in_millimetres_where_the_model_places_it(plant: "tuple[Any, Path]", tmp_path: Path) -> None:
    model, _ = plant
    db = mktree.create(tmp_path / "p.mkt")
    assert mktree.ifc.load(model, db, threads=2) == len(model.by_type("IfcElement"))
    r = db.read()
    slab = next(e for e in model.by_type("IfcSlab") if e.Name == "Slab 1-2")
    # Room (1, 2) is 6 m x 6 m at x 6 m, y 12 m; the slab is 200 mm deep below z = 0.
    assert r[slab.GlobalId].bounds == pytest.approx((6000, 12000, -200, 12000, 18000, 0), abs=1e-6)
    pipe = next(e for e in model.by_type("IfcPipeSegment") if e.Name == "Pipe 0-0-0")
    walls = [k for k in r.collide(pipe.GlobalId) if r[k].json()["class"] == "IfcWall"]
    assert len(walls) == 1  # the wall between rooms (0, 0) and (1, 0) it runs through


def test_placed_shapes_equal_ifcopenshells_world_coordinates(plant: "tuple[Any, Path]") -> None:
    # The loader triangulates each shared representation once and places it
    # itself; IfcOpenShell's own world-coordinate triangulation is the truth.
    import ifcopenshell.geom
    import numpy as np

    model, _ = plant
    ours = {o.key: o for o in mktree.ifc.shapes(model, threads=2)}
    settings = ifcopenshell.geom.settings()
    settings.set("use-world-coords", True)
    iterator = ifcopenshell.geom.iterator(settings, model, 2, exclude=list(mktree.ifc.DEFAULT_EXCLUDE))
    assert iterator.initialize()
    seen, shared = 0, set()
    while True:
        shape = iterator.get()
        o = ours[shape.guid]
        shared.add(shape.geometry.id)
        faces = np.asarray(shape.geometry.faces, dtype=np.int64).reshape(-1, 3)
        vertices = np.asarray(shape.geometry.verts, dtype=np.float64).reshape(-1, 3) * 1000.0
        assert np.array_equal(o.triangles, faces)
        assert np.allclose(o.vertices, vertices, rtol=0, atol=1e-6)
        seen += 1
        if not iterator.next():
            break
    assert seen == len(ours)
    assert len(shared) < seen / 10  # the model does share representations, so placing is exercised


def test_the_example_script_clashes_queries_and_draws(tmp_path: Path) -> None:
    png = tmp_path / "clashes.png"
    run = subprocess.run([sys.executable, str(HERE.parent / "examples" / "clash_report.py"), "-o", str(png)],
                         capture_output=True, text=True, check=True, cwd=HERE.parent / "examples")
    assert "IfcPipeSegment / IfcWall" in run.stdout and "box query" in run.stdout
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and os.path.getsize(png) > 5000


def test_a_model_without_shapes_loads_nothing(tmp_path: Path) -> None:
    model = ifcopenshell.file(schema="IFC4")
    model.createIfcProject(ifcopenshell.guid.new(), Name="Empty")
    assert list(mktree.ifc.shapes(model)) == []


def test_a_file_for_clash_tests_alone_has_no_levels_and_the_same_answers(
    plant: "tuple[Any, Path]", tmp_path: Path
) -> None:
    model, path = plant
    out = tmp_path / "clash-only.mkt"
    subprocess.run([sys.executable, "-m", "mktree.ifc", str(path), "-o", str(out), "--lod-levels", "1"],
                   capture_output=True, text=True, check=True)
    full = tmp_path / "full.mkt"
    mktree.ifc.load(model, full)
    with mktree.open(out, read_only=True) as one, mktree.open(full, read_only=True) as four:
        assert (one.lod_levels, four.lod_levels) == (1, 4)
        box = ((0.0, 0.0, -500.0), (20000.0, 20000.0, 3000.0))
        assert sorted(one.read().box(*box).keys) == sorted(four.read().box(*box).keys)
        assert one.check().ok


def test_names_none_and_empty_stay_as_the_model_has_them(tmp_path: Path) -> None:
    model = make_plant(1)
    walls = model.by_type("IfcWall")
    walls[0].Name = None
    walls[1].Name = ""
    objects = {o.key: o for o in mktree.ifc.shapes(model)}
    assert objects[walls[0].GlobalId].payload == {"class": "IfcWall", "name": None}
    assert objects[walls[1].GlobalId].payload == {"class": "IfcWall", "name": ""}
    assert objects[walls[2].GlobalId].payload == {"class": "IfcWall", "name": walls[2].Name}


def test_a_refused_model_leaves_no_file(tmp_path: Path) -> None:
    model = make_plant(1)
    model.by_type("IfcWall")[0].Name = "W" * 2000  # its payload would pass 1 KiB
    out = tmp_path / "refused.mkt"
    with pytest.raises(ValueError, match="a payload of"):
        mktree.ifc.load(model, out)
    assert not out.exists()
