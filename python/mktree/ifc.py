"""IFC models into mktree, through IfcOpenShell (``pip install mktree[ifc]``).

Each element with a body shape becomes one object: keyed by its GlobalId,
its triangles in world coordinates in millimetres, its IFC class and name
as a JSON payload (``{"class": "IfcWall", "name": "Wall 1"}``). The shapes
come from ``ifcopenshell.geom.iterator``, which triangulates on as many
threads as it is given (every core by default).

From Python::

    import mktree.ifc
    n = mktree.ifc.load("model.ifc", "model.mkt")

From the command line::

    python -m mktree.ifc model.ifc -o model.mkt
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from typing import Any, Dict, Iterator, List, Optional, Sequence, Tuple, Union

import numpy as np

from ._mktree import Database
from ._types import Object

__all__ = ["shapes", "load", "main"]

DEFAULT_EXCLUDE = ("IfcOpeningElement", "IfcSpace")
"""Classes left out by default: openings (voids, not things) and spaces (rooms, not things)."""


def shapes(
    model: Any,
    *,
    threads: Optional[int] = None,
    exclude: Sequence[str] = DEFAULT_EXCLUDE,
) -> Iterator[Object]:
    """The elements of ``model`` (an ``ifcopenshell.file``) that have a body
    shape, as objects keyed by GlobalId with ``{"class", "name"}`` payloads,
    in millimetres. ``threads`` is the iterator's (default: every core)."""
    import ifcopenshell.geom
    import ifcopenshell.util.shape

    # Local coordinates, placed here: the iterator then triangulates a
    # representation that many elements share (a pipe type, a wall type)
    # once. With its `use-world-coords` it triangulates every element anew,
    # 55 times slower on a model whose 3,164 elements share 7 (docs/clash.md).
    settings = ifcopenshell.geom.settings()  # type: ignore[no-untyped-call]
    # The iterator gives metres (SI) whatever the file's unit; mktree is in mm.
    scale = 1000.0
    iterator = ifcopenshell.geom.iterator(
        settings, model, threads or os.cpu_count() or 1, exclude=list(exclude) or None
    )
    if not iterator.initialize():
        return  # no element has a shape
    local: Dict[str, Tuple[Any, Any]] = {}  # geometry id -> (homogeneous vertices, faces)
    while True:
        shape = iterator.get()  # type: ignore[no-untyped-call]
        geometry = shape.geometry
        mesh = local.get(geometry.id)
        if mesh is None:
            vertices = ifcopenshell.util.shape.get_vertices(geometry)
            faces = ifcopenshell.util.shape.get_faces(geometry).astype(np.int64)
            mesh = (np.hstack([vertices, np.ones((len(vertices), 1))]), faces)
            local[geometry.id] = mesh
        homogeneous, faces = mesh
        if faces.size:
            placement = ifcopenshell.util.shape.get_shape_matrix(shape)
            vertices = (homogeneous @ placement.T)[:, :3] * scale
            # The iterator's class and name are the element's; an empty
            # name is looked up, to tell a Name of "" from none. (Looking up
            # every element was a quarter of this loop's time.)
            name: Optional[str] = shape.name
            if not name:
                name = getattr(model.by_id(shape.id), "Name", None)
            payload = {"class": shape.type, "name": name}
            yield Object(shape.guid, vertices, faces, payload, name or "")
        if not iterator.next():
            break


def load(
    model: Union[str, "os.PathLike[str]", Any],
    out: Union[str, "os.PathLike[str]", Database],
    *,
    threads: Optional[int] = None,
    block_size: int = 16384,
    lod_levels: int = 4,
    exclude: Sequence[str] = DEFAULT_EXCLUDE,
) -> int:
    """Bulk-loads the elements of ``model`` (a path or an
    ``ifcopenshell.file``) into ``out`` (an open ``Database``, or a path:
    created with ``block_size`` and ``lod_levels``, or opened if it exists,
    its tree replaced). ``lod_levels=1`` makes a file for clash tests and
    exact queries alone: it stores no levels of detail, so the load skips
    computing them (docs/clash.md). Returns the number of objects loaded."""
    import ifcopenshell

    if isinstance(model, (str, os.PathLike)):
        model = ifcopenshell.open(os.fspath(model))
    created: Optional[str] = None
    if isinstance(out, Database):
        db = out
    else:
        path = os.fspath(out)
        if os.path.exists(path):
            db = Database.open(path)
        else:
            db = Database.create(path, block_size=block_size, lod_levels=lod_levels)
            created = path
    try:
        objects: List[Object] = list(shapes(model, threads=threads, exclude=exclude))
        with db.write() as w:
            return w.bulk_load(objects)
    except BaseException:
        if created is not None:
            # A refused model leaves no file behind that looks like an index (as `mktree build`).
            db.close()
            os.remove(created)
        raise
    finally:
        if not isinstance(out, Database):
            db.close()


def main(argv: Optional[Sequence[str]] = None) -> int:
    """``python -m mktree.ifc MODEL.ifc -o OUT.mkt``: indexes an IFC model."""
    ap = argparse.ArgumentParser(
        prog="python -m mktree.ifc",
        description="Index an IFC model's elements in an mktree file, keyed by GlobalId.",
    )
    ap.add_argument("model", help="the .ifc file")
    ap.add_argument("-o", "--out", required=True, help="the .mkt file (created, or its tree replaced)")
    ap.add_argument("--threads", type=int, default=None, help="triangulation threads (default: every core)")
    ap.add_argument("--block-size", type=int, default=16384, help="bytes per block of a new file")
    ap.add_argument("--lod-levels", type=int, default=4,
                    help="levels of detail M of a new file (1: none, for clash tests and exact queries alone)")
    args = ap.parse_args(argv)
    started = time.perf_counter()
    try:
        n = load(args.model, args.out, threads=args.threads, block_size=args.block_size,
                 lod_levels=args.lod_levels)
    except Exception as e:  # one line and a non-zero exit, as the mktree CLI does
        print(f"error: {e}", file=sys.stderr)
        return 1
    print(f"{args.out}: {n} elements of {args.model} in {time.perf_counter() - started:.2f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
