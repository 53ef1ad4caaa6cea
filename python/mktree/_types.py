"""The plain values mktree takes and gives: objects, meshes and poses, as
named tuples (a tuple of the same fields will do wherever one is taken)."""

from __future__ import annotations

from typing import Any, NamedTuple, Optional, Tuple, Union

import numpy as np
import numpy.typing as npt

__all__ = ["Key", "Payload", "Mesh", "Object", "Pose"]

Key = Union[int, str, bytes]
"""An object's key: an int in 0 .. 2**64 - 1, or a str or bytes of at most
255 bytes (a str is stored as its UTF-8 bytes and read back as a str)."""

Payload = Union[bytes, bytearray, "dict[str, Any]", "list[Any]", None]
"""What is kept beside a key: bytes as they are, or a dict (or list) stored
as compact JSON; at most 1 KiB."""


class Mesh(NamedTuple):
    """A triangle mesh in millimetres."""

    vertices: npt.NDArray[np.float64]
    """(n, 3) float64 coordinates (any real dtype is converted)."""
    triangles: npt.NDArray[np.integer[Any]]
    """(m, 3) integer indices into ``vertices``."""


class Object(NamedTuple):
    """One object to store: its key, its mesh, a payload and a name."""

    key: Optional[Key]
    """The object's key; None: its position in a bulk load, or the next
    integer key for an insert."""
    vertices: npt.NDArray[np.float64]
    """(n, 3) float64 coordinates, mm."""
    triangles: npt.NDArray[np.integer[Any]]
    """(m, 3) integer indices into ``vertices``."""
    payload: Payload = None
    """Bytes, or a dict stored as JSON; read back as bytes (``Record.json()`` parses it)."""
    name: str = ""
    """A name kept in the key index."""

    @property
    def mesh(self) -> Mesh:
        """The object's mesh."""
        return Mesh(self.vertices, self.triangles)


class Pose(NamedTuple):
    """A rigid placement of a query mesh: rotated about its box centre by
    ``rotate_deg`` (degrees about x, then y, then z), then moved by
    ``translate`` (mm). A 4x4 affine matrix is taken wherever a Pose is."""

    translate: Tuple[float, float, float] = (0.0, 0.0, 0.0)
    """The move, mm."""
    rotate_deg: Tuple[float, float, float] = (0.0, 0.0, 0.0)
    """Rotations about x, y and z, degrees."""
