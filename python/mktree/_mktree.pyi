"""Types and documentation of the extension module ``mktree._mktree`` (the
engine's database, transactions and queries); ``mktree`` re-exports every
name here.

Coordinates are millimetres. A box is 6 floats, ``(min x, y, z, max x, y,
z)``. Queries read through the database's shared block cache unless given
``cache=False`` (then every block comes from the file and is counted, as the
``mktree`` command line counts). Long calls release the GIL, so threads can
query one file in parallel; a ``ReadTransaction`` may be shared by threads.
"""

from __future__ import annotations

import builtins
import os
import pathlib
from types import TracebackType
from typing import Any, Iterable, Iterator, List, Literal, Optional, Sequence, Tuple, Type, Union

from typing_extensions import final

import numpy as np
import numpy.typing as npt

from ._types import Key, Mesh, Object, Pose

__all__ = [
    "Answer",
    "ChangeStats",
    "CheckReport",
    "Clashes",
    "Compaction",
    "Database",
    "Hit",
    "HitIterator",
    "Info",
    "Near",
    "NearIterator",
    "RayHit",
    "RayIterator",
    "ReadTransaction",
    "Record",
    "Stats",
    "WriteTransaction",
    "_rust_box_seconds",
    "generate",
    "read_scene",
]

_Bounds = Tuple[float, float, float, float, float, float]
_Point = Union[Sequence[float], npt.NDArray[np.floating[Any]]]
_Path = Union[str, "os.PathLike[str]"]
_MeshLike = Union[Mesh, Tuple[npt.ArrayLike, npt.ArrayLike], Any]
"""A query mesh: an ``mktree.Mesh``, a ``(vertices, triangles)`` pair, or
anything with ``vertices`` and ``faces`` (a ``trimesh.Trimesh``)."""
_PoseLike = Union[Pose, Sequence[float], npt.ArrayLike, None]
"""A placement: an ``mktree.Pose``, a translation (3 numbers), a 4x4
affine matrix, or None (as it is)."""

@final
class Database:
    """An MKtree file. Any number of processes and threads may read it;
    one write transaction runs at a time. A context manager: ``with
    mktree.Database.open(path) as db:`` closes it at the end."""

    @classmethod
    def create(cls, path: _Path, block_size: int = 16384, lod_levels: int = 4) -> Database:
        """Creates a new file at ``path`` (it must not exist: ``FileExistsError``)
        with an empty tree. ``block_size``: bytes per block, a multiple of 16
        from 1,024 to 4,194,304; ``lod_levels``: M, the levels of detail (1 to 16).
        Wrong settings raise ``ValueError``."""
    @classmethod
    def open(cls, path: _Path, read_only: bool = False) -> Database:
        """Opens an existing file (``FileNotFoundError`` if there is none);
        ``read_only=True`` opens it to read only, and ``write`` then raises
        ``ReadOnlyError``. A file that is not mktree's raises ``CorruptionError``."""
    def read(self) -> ReadTransaction:
        """A read transaction: a snapshot of the newest commit, which later
        commits do not change."""
    def write(self, wait: bool = False) -> WriteTransaction:
        """The write transaction. One runs at a time: another thread's makes
        this wait; another process's raises ``LockedError`` unless ``wait=True``.
        A second one begun by the thread whose transaction is open would wait
        for ever: it raises ``mktree.Error`` instead."""
    def stats(self) -> Optional[Info]:
        """The committed tree's counts, blocks and fill; None with no tree yet."""
    def check(self) -> CheckReport:
        """Verifies every checksum and structural rule of the newest commit
        (a reader: writers are not kept out)."""
    def compact(self, wait: bool = False) -> Compaction:
        """Gives the file's free blocks back to the file system."""
    @property
    def path(self) -> pathlib.Path:
        """The file's path."""
    @property
    def block_size(self) -> int:
        """Bytes per block."""
    @property
    def lod_levels(self) -> int:
        """M, the levels of detail per node."""
    @property
    def read_only(self) -> bool:
        """Opened with ``read_only=True``."""
    @property
    def closed(self) -> bool:
        """True once ``close`` ran."""
    def close(self) -> None:
        """Closes the database (the file stays open while its transactions
        and iterators live)."""
    def __enter__(self) -> Database: ...
    def __exit__(
        self,
        exc_type: Optional[Type[BaseException]],
        exc: Optional[BaseException],
        tb: Optional[TracebackType],
    ) -> Literal[False]: ...

@final
class WriteTransaction:
    """The one write transaction: a bulk load, or changes by key, committed
    atomically (the old tree or the new one, never a mix). A context
    manager: ``with db.write() as w:`` commits when the block ends and
    aborts when it raises. Dropped unended, it aborts. One transaction
    writes one tree: a bulk load, or inserts, updates, removals and moves."""

    def bulk_load(self, objects: Iterable[Union[Object, Tuple[Any, ...]]]) -> int:
        """Replaces the tree with one bulk-loaded from ``objects``:
        ``mktree.Object`` (or tuples ``(key, vertices, triangles[, payload[,
        name]])``), vertices (n, 3) float64 in mm, triangles (m, 3) integers.
        Every object is checked first: a malformed array (shape, dtype, NaN,
        an index out of range) raises ``ValueError`` naming the object, and
        a repeated key ``DuplicateKeyError``, before anything is written.
        A key of None is the object's position. Returns the count loaded."""
    def insert(self, object: Union[Object, Tuple[Any, ...]]) -> Key:
        """Adds ``object``; its key None takes the next integer key. Returns
        the key; a key already stored raises ``DuplicateKeyError``."""
    def update(self, object: Union[Object, Tuple[Any, ...]]) -> None:
        """Replaces the stored object with ``object``'s key (``KeyNotFoundError``
        if there is none)."""
    def remove(self, key: Key, missing_ok: bool = False) -> bool:
        """Removes the object with ``key``; returns whether there was one. A
        missing key raises ``KeyNotFoundError`` unless ``missing_ok``."""
    def move_by(self, key: Key, offset: _Point) -> None:
        """Moves the object with ``key`` by ``offset`` (dx, dy, dz), mm."""
    def get(self, key: Key) -> Optional[Object]:
        """The object with ``key`` as this transaction has it (its changes
        included), or None."""
    def commit(self) -> ChangeStats:
        """Commits; returns what the commit wrote."""
    def abort(self) -> None:
        """Aborts: the committed state stays as it was."""
    @property
    def closed(self) -> bool:
        """True once committed or aborted."""
    def __enter__(self) -> WriteTransaction: ...
    def __exit__(
        self,
        exc_type: Optional[Type[BaseException]],
        exc: Optional[BaseException],
        tb: Optional[TracebackType],
    ) -> Literal[False]: ...

@final
class ReadTransaction:
    """A snapshot of the committed tree and its queries. Region and
    collision queries answer the objects whose triangles meet the shape
    (closed sets: touching counts) at level ``lod`` (None: M, exact; below
    M, a superset), in at most ``budget`` block reads when given. A context
    manager; ``r[key]``, ``key in r`` and ``len(r)`` work by key."""

    def box(
        self,
        lo: _Point,
        hi: _Point,
        *,
        lod: Optional[int] = None,
        budget: Optional[int] = None,
        cache: bool = True,
    ) -> Answer:
        """The objects that meet the closed box from ``lo`` to ``hi``."""
    def sphere(
        self,
        center: _Point,
        radius: float,
        *,
        lod: Optional[int] = None,
        budget: Optional[int] = None,
        cache: bool = True,
    ) -> Answer:
        """The objects that meet the closed ball of ``radius`` about ``center``."""
    def frustum(
        self,
        eye: _Point,
        target: _Point,
        fov_deg: float,
        aspect: float,
        near: float,
        far: float,
        *,
        lod: Optional[int] = None,
        budget: Optional[int] = None,
        cache: bool = True,
    ) -> Answer:
        """The objects that meet a camera's view frustum (vertical field of
        view ``fov_deg``, width over height ``aspect``, 0 < near < far)."""
    def collide(
        self,
        mesh: Union[_MeshLike, Key],
        pose: _PoseLike = None,
        *,
        clearance: float = 0.0,
        lod: Optional[int] = None,
        budget: Optional[int] = None,
        cache: bool = True,
    ) -> Answer:
        """The objects that ``mesh`` placed by ``pose`` touches, or comes
        within ``clearance`` mm of. ``mesh`` may be the key of a stored
        object, which is then left out of its own answer."""
    def clearance(
        self,
        mesh: Union[_MeshLike, Key],
        distance: float,
        pose: _PoseLike = None,
        *,
        lod: Optional[int] = None,
        budget: Optional[int] = None,
        cache: bool = True,
    ) -> Answer:
        """The objects within ``distance`` mm of ``mesh`` placed by ``pose``."""
    def clash(self, *, clearance: float = 0.0, lod: Optional[int] = None) -> Clashes:
        """Every pair of stored objects that touch, or come within ``clearance`` mm."""
    def nearest(self, point: _Point, k: int = 1, *, cache: bool = True) -> List[Near]:
        """The ``k`` objects nearest ``point`` by exact distance to their
        triangles, nearest first (ties by id)."""
    def ray(
        self,
        origin: _Point,
        direction: _Point,
        *,
        max_distance: Optional[float] = None,
        k: Optional[int] = None,
        cache: bool = True,
    ) -> List[RayHit]:
        """The objects a ray meets (up to ``max_distance`` mm), in order of
        distance: all of them, or the first ``k``."""
    def iter_box(
        self,
        lo: _Point,
        hi: _Point,
        *,
        lod: Optional[int] = None,
        budget: Optional[int] = None,
        cache: bool = True,
    ) -> HitIterator:
        """``box``, lazily: blocks are read as the iteration needs them."""
    def iter_sphere(
        self,
        center: _Point,
        radius: float,
        *,
        lod: Optional[int] = None,
        budget: Optional[int] = None,
        cache: bool = True,
    ) -> HitIterator:
        """``sphere``, lazily."""
    def iter_frustum(
        self,
        eye: _Point,
        target: _Point,
        fov_deg: float,
        aspect: float,
        near: float,
        far: float,
        *,
        lod: Optional[int] = None,
        budget: Optional[int] = None,
        cache: bool = True,
    ) -> HitIterator:
        """``frustum``, lazily."""
    def iter_collide(
        self,
        mesh: Union[_MeshLike, Key],
        pose: _PoseLike = None,
        *,
        clearance: float = 0.0,
        lod: Optional[int] = None,
        budget: Optional[int] = None,
        cache: bool = True,
    ) -> HitIterator:
        """``collide``, lazily (a stored object given by key is not left out)."""
    def iter_nearest(self, point: _Point, *, cache: bool = True) -> NearIterator:
        """Every object by distance from ``point``, nearest first, lazily."""
    def iter_ray(
        self,
        origin: _Point,
        direction: _Point,
        *,
        max_distance: Optional[float] = None,
        cache: bool = True,
    ) -> RayIterator:
        """Every object a ray meets, nearest first, lazily."""
    def get(self, key: Key) -> Optional[Record]:
        """The object with ``key`` (id, exact box, payload), from the key
        index in its height of block reads; None if there is none."""
    def mesh(self, key: Key) -> Optional[Mesh]:
        """The exact mesh of the object with ``key``, or None."""
    def object(self, key: Key) -> Optional[Object]:
        """The object with ``key`` whole (key, mesh, payload, name), or None."""
    def info(self) -> Optional[Info]:
        """The snapshot's tree: counts, blocks and fill; None with no tree."""
    def close(self) -> None:
        """Ends the snapshot, so writers may reuse the blocks it pins (an
        iterator still open keeps it until the iterator goes)."""
    @property
    def closed(self) -> bool:
        """True once closed."""
    def __getitem__(self, key: Key, /) -> Record: ...
    def __contains__(self, key: builtins.object, /) -> bool: ...
    def __len__(self) -> int: ...
    def __enter__(self) -> ReadTransaction: ...
    def __exit__(
        self,
        exc_type: Optional[Type[BaseException]],
        exc: Optional[BaseException],
        tb: Optional[TracebackType],
    ) -> Literal[False]: ...

@final
class Answer:
    """A region, collision or clearance query's answer: a sequence of the
    keys found (sorted by object id), with what the query read. The list
    and the arrays are made when first asked for."""

    @property
    def keys(self) -> List[Key]:
        """The keys found, as a list."""
    @property
    def ids(self) -> npt.NDArray[np.uint32]:
        """The object ids found (sorted), as a numpy array."""
    def key_array(self) -> npt.NDArray[Any]:
        """The keys as one numpy array: uint64 when every key is an int, a
        unicode array for str keys, an object array for a mix."""
    @property
    def maybe(self) -> npt.NDArray[np.uint32]:
        """With a budget: ids of objects seen but not refined to the level asked for."""
    @property
    def level(self) -> int:
        """The level asked for (M: exact)."""
    @property
    def level_reached(self) -> int:
        """The coarsest level an undecided candidate stopped at (``level``
        when the budget sufficed)."""
    @property
    def unexplored_nodes(self) -> int:
        """With a budget: subtrees left unread."""
    @property
    def stats(self) -> Stats:
        """What the query read and decided."""
    def __len__(self) -> int: ...
    def __getitem__(self, i: int, /) -> Key: ...
    def __iter__(self) -> Iterator[Key]: ...
    def __contains__(self, key: object, /) -> bool: ...

@final
class Clashes:
    """Every clashing pair of objects, as keys (lower id first), sorted by
    id, with the run's reads: a sequence of ``(key_a, key_b)``."""

    @property
    def pairs(self) -> List[Tuple[Key, Key]]:
        """The pairs as a list."""
    @property
    def id_pairs(self) -> npt.NDArray[np.uint32]:
        """The pairs as object ids, a numpy array of shape (n, 2)."""
    def key_arrays(self) -> Tuple[npt.NDArray[Any], npt.NDArray[Any]]:
        """The pairs' keys as two numpy arrays (see ``Answer.key_array``)."""
    @property
    def level(self) -> int:
        """The level of the run (M: exact pairs)."""
    @property
    def clearance(self) -> float:
        """The clearance, mm."""
    @property
    def file_blocks(self) -> int:
        """Blocks in the file, to set the reads against."""
    @property
    def stats(self) -> Stats:
        """What the run read and decided."""
    def __len__(self) -> int: ...
    def __getitem__(self, i: int, /) -> Tuple[Key, Key]: ...
    def __iter__(self) -> Iterator[Tuple[Key, Key]]: ...

@final
class Stats:
    """What a query read and decided, as the engine counts it where it reads."""

    @property
    def block_reads(self) -> int:
        """Blocks read from the file (node, geometry, key index, other);
        cache hits are not reads."""
    @property
    def node_reads(self) -> int:
        """Node blocks read."""
    @property
    def geometry_reads(self) -> int:
        """Geometry blocks read."""
    @property
    def key_reads(self) -> int:
        """Key index blocks read."""
    @property
    def cache_hits(self) -> int:
        """Blocks found in the cache instead of read."""
    @property
    def nodes_visited(self) -> int:
        """Tree nodes entered."""
    @property
    def leaves_visited(self) -> int:
        """Leaves entered."""
    @property
    def confirmed(self) -> List[int]:
        """Per level k = 1 .. M: objects confirmed there."""
    @property
    def rejected(self) -> List[int]:
        """Per level k = 1 .. M: objects rejected there."""
    @property
    def pruned(self) -> int:
        """Subtrees ruled out by their boxes."""
    @property
    def geometry_tests(self) -> int:
        """Objects whose triangles were read and tested."""
    @property
    def triangles_tested(self) -> int:
        """Triangle tests made."""
    @property
    def seconds(self) -> float:
        """The query's time in the engine."""

@final
class Hit:
    """An object a lazy query accepted."""

    @property
    def key(self) -> Key:
        """Its key."""
    @property
    def id(self) -> int:
        """Its id in the tree."""
    @property
    def bounds(self) -> _Bounds:
        """Its box as stored (rounded outward)."""
    @property
    def level(self) -> int:
        """The level of the bound that decided it."""
    @property
    def proof(self) -> str:
        """What decided it: ``"inside_node"``, ``"face"``, ``"cell"``,
        ``"exact"`` or (below M) ``"candidate"``."""

@final
class Near:
    """An object at its distance from a point."""

    @property
    def key(self) -> Key:
        """Its key."""
    @property
    def id(self) -> int:
        """Its id in the tree."""
    @property
    def distance(self) -> float:
        """From the point to the object's surface, mm."""

@final
class RayHit:
    """Where a ray first meets an object."""

    @property
    def key(self) -> Key:
        """Its key."""
    @property
    def id(self) -> int:
        """Its id in the tree."""
    @property
    def t(self) -> float:
        """The distance from the ray's origin, mm."""
    @property
    def point(self) -> Tuple[float, float, float]:
        """The point at distance t."""

@final
class HitIterator(Iterator[Hit]):
    """Hits of a region or collision query, one at a time; only the blocks
    the hits so far needed are read. Use it on the thread that made it."""

    def __iter__(self) -> HitIterator: ...
    def __next__(self) -> Hit: ...
    @property
    def stats(self) -> Stats:
        """What the hits so far cost."""

@final
class NearIterator(Iterator[Near]):
    """Objects by distance from a point, nearest first, one at a time."""

    def __iter__(self) -> NearIterator: ...
    def __next__(self) -> Near: ...
    @property
    def stats(self) -> Stats:
        """What the objects so far cost."""

@final
class RayIterator(Iterator[RayHit]):
    """Objects a ray meets, nearest first, one at a time."""

    def __iter__(self) -> RayIterator: ...
    def __next__(self) -> RayHit: ...
    @property
    def stats(self) -> Stats:
        """What the hits so far cost."""

@final
class Record:
    """One object found by key: its id, exact box and payload."""

    @property
    def key(self) -> Key:
        """Its key."""
    @property
    def id(self) -> int:
        """Its id in the tree."""
    @property
    def bounds(self) -> _Bounds:
        """Its exact box."""
    @property
    def payload(self) -> bytes:
        """The payload as stored (a dict was stored as JSON)."""
    def json(self) -> Any:
        """The payload parsed as JSON; None without a payload."""

@final
class Info:
    """A file's tree, from its meta block."""

    @property
    def txn(self) -> int:
        """The committed transaction the snapshot is."""
    @property
    def block_size(self) -> int:
        """Bytes per block."""
    @property
    def lod_levels(self) -> int:
        """M, the levels of detail."""
    @property
    def file_blocks(self) -> int:
        """Blocks in the file."""
    @property
    def free_blocks(self) -> int:
        """Blocks on the free list."""
    @property
    def objects(self) -> int:
        """Objects stored."""
    @property
    def nodes(self) -> int:
        """Tree nodes."""
    @property
    def leaves(self) -> int:
        """Leaves."""
    @property
    def depth(self) -> int:
        """Deepest level (the root is 0)."""
    @property
    def node_blocks(self) -> int:
        """Blocks of nodes."""
    @property
    def geometry_blocks(self) -> int:
        """Blocks of geometry."""
    @property
    def node_fill(self) -> float:
        """Bytes of node records over the node blocks' bytes."""
    @property
    def geometry_fill(self) -> float:
        """Bytes of geometry records over the geometry blocks' bytes."""
    @property
    def triangles(self) -> int:
        """Triangles stored."""
    @property
    def vertices(self) -> int:
        """Vertices stored."""
    @property
    def scene_bounds(self) -> _Bounds:
        """The scene's box."""
    @property
    def build_seconds(self) -> float:
        """How long building the tree took."""

@final
class CheckReport:
    """What ``check`` found; true when no fault."""

    @property
    def ok(self) -> bool:
        """No fault was found."""
    @property
    def txn(self) -> int:
        """The commit checked."""
    @property
    def file_blocks(self) -> int:
        """Blocks in the file."""
    @property
    def blocks_by_type(self) -> dict[str, int]:
        """Blocks counted by type."""
    @property
    def free_blocks(self) -> int:
        """Blocks on the free list."""
    @property
    def objects(self) -> int:
        """Objects found."""
    @property
    def nodes(self) -> int:
        """Nodes found."""
    @property
    def interrupted(self) -> bool:
        """A write transaction was interrupted; the next one cleans up after it."""
    @property
    def warnings(self) -> List[str]:
        """Damage that loses nothing (a torn slot copy)."""
    @property
    def faults(self) -> List[str]:
        """Every fault found."""
    def __bool__(self) -> bool: ...

@final
class Compaction:
    """What ``compact`` did."""

    @property
    def blocks_before(self) -> int:
        """The file's blocks before."""
    @property
    def blocks_after(self) -> int:
        """The file's blocks after."""
    @property
    def free_after(self) -> int:
        """Blocks still free after (held for older readers, or holes)."""
    @property
    def rewrites(self) -> int:
        """Times the tree was moved."""

@final
class ChangeStats:
    """What a commit wrote."""

    @property
    def changes(self) -> int:
        """Objects inserted, updated and removed."""
    @property
    def blocks_written(self) -> int:
        """Blocks written: node, geometry, key index, meta."""
    @property
    def blocks_freed(self) -> int:
        """Blocks of the old tree the new one no longer reaches."""
    @property
    def blocks_read(self) -> int:
        """Blocks read to find and rewrite the changed objects' paths."""
    @property
    def in_place(self) -> bool:
        """The changes were written copy on write in place; False: the tree
        was written whole."""

def generate(preset: str, objects: Optional[int] = None, seed: int = 0) -> List[Object]:
    """A generated ship-outfitting scene (``mktree gen``'s presets:
    ``tanker1``, ``tanker2``, ``tanker3``, ``ship``), keyed by id."""

def read_scene(path: _Path, gltf_scale: float = 1000.0) -> List[Object]:
    """The objects of a scene file (OBJ, STL, glTF, or a folder of OBJ and
    STL files), keyed by id, as the ``mktree`` command line imports them."""

def _rust_box_seconds(r: ReadTransaction, boxes: Sequence[Sequence[float]], repeats: int) -> float:
    """For ``benchmarks/box_query.py``: seconds per box query through the
    Rust API on ``r``'s snapshot and cache, with no Python between queries."""
