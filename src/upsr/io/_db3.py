"""A ROS 2 sqlite3 storage file (``.db3``) read without ``metadata.yaml``.

librealsense 2.59 and later record ``.db3`` files alone (no bag folder, no ``metadata.yaml``),
which ``rosbags``' reader refuses. This reader takes the topics and messages from the sqlite
tables themselves (``topics``: id, name, type, serialization_format; ``messages``: topic_id,
timestamp, data) and offers the small part of ``rosbags.highlevel.AnyReader``'s interface that
:mod:`upsr.io.rosbag` uses: ``connections`` (``topic``, ``msgtype``, ``msgcount``),
``messages(connections=...)`` yielding ``(connection, timestamp_ns, raw)`` in time order, and
``deserialize(raw, msgtype)`` (CDR, the standard message types of ``rosbags``).
"""

from __future__ import annotations

import sqlite3
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from upsr.errors import InputError

__all__ = ["Db3Connection", "Db3Reader"]


@dataclass(frozen=True)
class Db3Connection:
    """One topic of the file."""

    id: int
    topic: str
    msgtype: str
    msgcount: int


class Db3Reader:
    """Read a ``.db3`` file's tables (see the module docstring). Use as a context manager."""

    is_ros2 = True

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        uri = f"file:{self.path.resolve()}?mode=ro"
        try:
            self._db = sqlite3.connect(uri, uri=True)
            rows = self._db.execute(
                "SELECT t.id, t.name, t.type, t.serialization_format, "
                "(SELECT COUNT(*) FROM messages m WHERE m.topic_id = t.id) FROM topics t"
            ).fetchall()
        except sqlite3.Error as e:
            raise InputError(f"{path}: not a ROS 2 sqlite3 bag ({e})") from None
        self.connections = [
            Db3Connection(int(i), str(n), str(t), int(c))
            for i, n, t, fmt, c in rows
            if str(fmt) == "cdr"
        ]
        self._typestore: Any = None

    def open(self) -> None:
        """(Already open: kept for the AnyReader interface.)"""

    def close(self) -> None:
        """Close the database."""
        self._db.close()

    def __enter__(self) -> Db3Reader:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def messages(self, connections: list[Any] | None = None) -> Iterator[tuple[Any, int, bytes]]:
        """(connection, timestamp ns, CDR bytes) of ``connections`` in time order."""
        conns = {c.id: c for c in (connections or self.connections)}
        if not conns:
            return
        marks = ",".join("?" * len(conns))
        cur = self._db.execute(
            f"SELECT topic_id, timestamp, data FROM messages WHERE topic_id IN ({marks}) "
            "ORDER BY timestamp, id",
            list(conns),
        )
        for tid, ts, data in cur:
            yield conns[int(tid)], int(ts), bytes(data)

    def deserialize(self, raw: bytes, msgtype: str) -> Any:
        """A CDR message of a standard type (``rosbags`` typestore)."""
        if self._typestore is None:
            from rosbags.typesys import Stores, get_typestore

            self._typestore = get_typestore(Stores.LATEST)
        return self._typestore.deserialize_cdr(raw, msgtype)
