"""mktree: a persistent spatial index of 3D triangle meshes.

One ``.mkt`` file holds a binary tree of bounding boxes (the MKtree) over
the objects, with coarser stand-ins stored where they pay; queries read as
few blocks as they can and count each one. Quick start::

    import numpy as np
    import mktree

    db = mktree.Database.create("plant.mkt")
    cube = (np.array([[0, 0, 0], [1000, 0, 0], [0, 1000, 0], [0, 0, 1000]], float),
            np.array([[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]]))
    with db.write() as w:                       # commits at the end of the block
        w.bulk_load(mktree.Object(i, cube[0] + 2000 * i, cube[1]) for i in range(10))
    with db.read() as r:
        hits = r.box((0, 0, 0), (2500, 2500, 2500))
        print(hits.keys, hits.stats.block_reads)   # [0, 1] and the blocks read

The classes are documented in ``mktree/_mktree.pyi``; interop with trimesh
is ``from_trimesh`` and ``to_trimesh``, with IfcOpenShell ``mktree.ifc``.
"""

from __future__ import annotations

from ._errors import (
    ClosedError,
    CorruptionError,
    DuplicateKeyError,
    Error,
    KeyNotFoundError,
    LockedError,
    ReadOnlyError,
)
from ._mktree import (
    Answer,
    ChangeStats,
    CheckReport,
    Clashes,
    Compaction,
    Database,
    Hit,
    HitIterator,
    Info,
    Near,
    NearIterator,
    RayHit,
    RayIterator,
    ReadTransaction,
    Record,
    Stats,
    WriteTransaction,
    generate,
    read_scene,
)
from ._trimesh import from_trimesh, to_trimesh
from ._types import Key, Mesh, Object, Payload, Pose

__version__ = "0.1.0"

create = Database.create
"""``mktree.create(path, block_size=16384, lod_levels=4)``: ``Database.create``."""
open = Database.open  # noqa: A001 (the module's own open, as sqlite3.connect)
"""``mktree.open(path, read_only=False)``: ``Database.open``."""

__all__ = [
    "Answer",
    "ChangeStats",
    "CheckReport",
    "Clashes",
    "ClosedError",
    "Compaction",
    "CorruptionError",
    "Database",
    "DuplicateKeyError",
    "Error",
    "Hit",
    "HitIterator",
    "Info",
    "Key",
    "KeyNotFoundError",
    "LockedError",
    "Mesh",
    "Near",
    "NearIterator",
    "Object",
    "Payload",
    "Pose",
    "RayHit",
    "RayIterator",
    "ReadOnlyError",
    "ReadTransaction",
    "Record",
    "Stats",
    "WriteTransaction",
    "create",
    "from_trimesh",
    "generate",
    "open",
    "read_scene",
    "to_trimesh",
]
