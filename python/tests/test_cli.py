"""The package's answers equal the mktree command line's on the same file,
block reads included (cold reads: ``cache=False``), and a file the package
loads from numpy answers as the CLI's build of the same OBJ does."""

from __future__ import annotations

import json
import random
import subprocess
from pathlib import Path
from typing import Any, List

import pytest

import mktree


def run_json(cli: str, *args: str) -> Any:
    out = subprocess.run([cli, *args, "--json"], check=True, capture_output=True, text=True)
    return json.loads(out.stdout)


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory, cli: str) -> "tuple[Path, Path]":
    """tanker1 as OBJ, built by the CLI and loaded by the package from numpy arrays."""
    d = tmp_path_factory.mktemp("cli")
    obj = d / "t1.obj"
    subprocess.run([cli, "gen", "tanker1", "-o", str(obj)], check=True, capture_output=True)
    subprocess.run([cli, "build", str(obj), "-o", str(d / "cli.mkt")], check=True, capture_output=True)
    db = mktree.create(d / "py.mkt")
    with db.write() as w:
        w.bulk_load(mktree.read_scene(obj))
    db.close()
    return d / "cli.mkt", d / "py.mkt"


def boxes(info: mktree.Info, n: int, extent: float) -> List["tuple[float, ...]"]:
    rng = random.Random(37)
    lo, hi = info.scene_bounds[:3], info.scene_bounds[3:]
    out = []
    for _ in range(n):
        c = [rng.uniform(a, b) for a, b in zip(lo, hi)]
        h = [(b - a) * extent / 2 for a, b in zip(lo, hi)]
        out.append(tuple(c[i] - h[i] for i in range(3)) + tuple(c[i] + h[i] for i in range(3)))
    return out


def test_region_queries_equal_the_clis(files: "tuple[Path, Path]", cli: str) -> None:
    cli_file, py_file = files
    with mktree.open(py_file, read_only=True) as db:
        r = db.read()
        info = r.info()
        assert info is not None and info.objects == 222
        for b in boxes(info, 12, 0.05) + boxes(info, 4, 0.3):
            arg = ",".join(repr(x) for x in b)
            a = r.box(b[:3], b[3:], cache=False)
            same_file = run_json(cli, "query", str(py_file), f"--box={arg}")
            assert a.keys == same_file["keys"] and a.ids.tolist() == same_file["objects"]
            assert a.stats.block_reads == same_file["block_reads"]["total"]
            assert a.keys == run_json(cli, "query", str(cli_file), f"--box={arg}")["keys"]
            lod1 = r.box(b[:3], b[3:], lod=1, cache=False)
            assert lod1.keys == run_json(cli, "query", str(py_file), f"--box={arg}", "--lod=1")["keys"]
        c = [(info.scene_bounds[i] + info.scene_bounds[i + 3]) / 2 for i in range(3)]
        s = r.sphere(c, 3000.0, cache=False)
        assert s.keys == run_json(cli, "query", str(py_file), f"--sphere={c[0]},{c[1]},{c[2]},3000")["keys"]
        eye, target = (c[0] - 20000, c[1], c[2]), c
        f = r.frustum(eye, target, 40.0, 1.5, 100.0, 40000.0, cache=False)
        cam = ",".join(str(x) for x in [*eye, *target, 40.0, 1.5, 100.0, 40000.0])
        assert f.keys == run_json(cli, "query", str(py_file), f"--frustum={cam}")["keys"]
        assert len(s) > 0 and len(f) > 0


def test_collisions_and_clashes_equal_the_clis(files: "tuple[Path, Path]", cli: str) -> None:
    _, py_file = files
    with mktree.open(py_file, read_only=True) as db:
        r = db.read()
        for key, t, rot, d in [(5, (0, 0, 0), (0, 0, 0), 0.0), (40, (120, -35, 10), (0, 0, 30), 0.0),
                               (100, (0, 0, 0), (0, 0, 0), 50.0), (7, (300, 0, 0), (10, 20, 30), 25.0)]:
            a = r.collide(key, mktree.Pose(t, rot), clearance=d, cache=False)
            expected = run_json(cli, "collide", str(py_file), f"--object={key}",
                                f"--translate={t[0]},{t[1]},{t[2]}", f"--rotate-deg={rot[0]},{rot[1]},{rot[2]}",
                                f"--clearance={d}")
            assert a.keys == expected["keys"] and a.stats.block_reads == expected["block_reads"]["total"]
        for d in (0.0, 50.0):
            c = r.clash(clearance=d)
            expected = run_json(cli, "clash", str(py_file), f"--clearance={d}")
            assert c.id_pairs.tolist() == expected["pairs"] and len(c) > 0
            # Keys are ids here (read_scene keys objects by position).
            assert [list(p) for p in c.pairs] == expected["pairs"]


def test_nearest_ray_and_lookup_equal_the_clis_batch_and_get(files: "tuple[Path, Path]", cli: str) -> None:
    _, py_file = files
    r = mktree.open(py_file, read_only=True).read()
    info = r.info()
    assert info is not None
    c = [(info.scene_bounds[i] + info.scene_bounds[i + 3]) / 2 for i in range(3)]
    origin = (info.scene_bounds[0] - 1000, c[1], c[2])
    requests = [
        {"query": "nearest", "point": c, "k": 5},
        {"query": "ray", "origin": origin, "direction": [1, 0, 0], "all": True},
    ]
    batch = subprocess.run([cli, "batch", str(py_file)], input="\n".join(json.dumps(q) for q in requests) + "\n",
                           check=True, capture_output=True, text=True)
    nearest, ray = (json.loads(line) for line in batch.stdout.splitlines())
    near = r.nearest(c, 5)
    assert [n.key for n in near] == nearest["keys"]
    assert [n.distance for n in near] == pytest.approx(nearest["distances"])
    hits = r.ray(origin, (1, 0, 0))
    assert [h.key for h in hits] == ray["keys"] and [h.t for h in hits] == pytest.approx(ray["distances"])
    got = run_json(cli, "get", str(py_file), "--key=17")
    rec = r[17]
    assert rec.id == got["id"] and list(rec.bounds) == pytest.approx(got["box"])
