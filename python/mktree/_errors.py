"""The exceptions mktree raises (besides ``ValueError``, ``TypeError`` and
``OSError`` for what the caller passed or the system refused). Each carries
the engine's message."""

from __future__ import annotations

__all__ = [
    "Error",
    "LockedError",
    "ReadOnlyError",
    "CorruptionError",
    "DuplicateKeyError",
    "KeyNotFoundError",
    "ClosedError",
]


class Error(Exception):
    """The engine refused: the file, a transaction's state, another process."""


class LockedError(Error):
    """Another process is writing the file (``db.write(wait=True)`` waits for it)."""


class ReadOnlyError(Error):
    """The file was opened with ``read_only=True``."""


class CorruptionError(Error):
    """The file's bytes are damaged or not an mktree file; the message names
    the block, the record and the field."""


class DuplicateKeyError(Error, ValueError):
    """Two objects of a bulk load share a key, or an insert's key is already stored."""


class KeyNotFoundError(Error, KeyError):
    """No object has the key (``update``, ``remove``, ``move_by``, ``r[key]``)."""

    def __str__(self) -> str:
        # KeyError's str() is the repr of its argument; the message reads better plain.
        return str(self.args[0]) if self.args else ""


class ClosedError(Error):
    """A database or transaction used after it was closed, committed or aborted."""
