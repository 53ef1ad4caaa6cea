"""trimesh in and out: a trimesh ``Trimesh`` or ``Scene`` as mktree objects,
and a query's answer back as trimesh meshes. trimesh is imported only when
these are called (``pip install mktree[trimesh]``)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Iterable, List, Optional

import numpy as np

from ._types import Key, Object

if TYPE_CHECKING:
    from ._mktree import ReadTransaction

__all__ = ["from_trimesh", "to_trimesh"]


def from_trimesh(scene_or_mesh: Any, key: Optional[Key] = None) -> List[Object]:
    """The objects of a ``trimesh.Scene`` (one per node that has geometry,
    in world coordinates, keyed by node name) or of one ``trimesh.Trimesh``
    (keyed by ``key``, None: by position). Coordinates are taken as
    millimetres; scale the scene first if it is in other units."""
    geometry = getattr(scene_or_mesh, "geometry", None)
    graph = getattr(scene_or_mesh, "graph", None)
    if isinstance(geometry, dict) and graph is not None:
        objects: List[Object] = []
        for node in graph.nodes_geometry:
            transform, name = graph[node]
            mesh = geometry[name]
            faces = np.asarray(getattr(mesh, "faces", ()))
            if faces.size == 0:
                continue  # points and paths have no triangles
            vertices = np.asarray(mesh.vertices, dtype=np.float64)
            t = np.asarray(transform, dtype=np.float64)
            world = vertices @ t[:3, :3].T + t[:3, 3]
            objects.append(Object(str(node), world, faces, None, str(name)))
        return objects
    if hasattr(scene_or_mesh, "vertices") and hasattr(scene_or_mesh, "faces"):
        return [
            Object(
                key,
                np.asarray(scene_or_mesh.vertices, dtype=np.float64),
                np.asarray(scene_or_mesh.faces),
                None,
                str(getattr(scene_or_mesh.metadata, "get", lambda *_: "")("name", "") or ""),
            )
        ]
    raise TypeError(f"from_trimesh takes a trimesh.Scene or trimesh.Trimesh, not {type(scene_or_mesh).__name__}")


def to_trimesh(r: "ReadTransaction", keys: Iterable[Key]) -> Any:
    """The stored objects of ``keys`` (an ``Answer`` will do) as one
    ``trimesh.Scene``, a node per object named by its key."""
    import trimesh

    scene = trimesh.Scene()
    for key in keys:
        mesh = r.mesh(key)
        if mesh is None:
            raise KeyError(key)
        name = key if isinstance(key, str) else repr(key)
        scene.add_geometry(
            trimesh.Trimesh(vertices=mesh.vertices, faces=mesh.triangles, process=False),
            node_name=name,
            geom_name=name,
        )
    return scene
