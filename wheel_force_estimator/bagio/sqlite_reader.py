# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Bulk payloads of a rosbag2 sqlite3 storage file: aggregate queries over rowid ranges.

SQLite itself concatenates the blobs of a batch and lists (topic id, length) and timestamps as
text, so Python never touches a row; the next query runs in a worker (SQLite releases the GIL)
while the current batch is decoded.  Batches go to the per-topic sinks of :mod:`.storage`.
"""
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
import sqlite3
from typing import Sequence

import numpy as np

from wheel_force_estimator.bagio.mcap_records import topic_type
from wheel_force_estimator.core.errors import BagError

# Rows per sqlite3 query: bounds memory and stays far below SQLITE_MAX_LENGTH (1e9 bytes)
# for the concatenated payloads of one batch.
_SQLITE_BATCH = 20000
# Read pages through mmap instead of copying them into SQLite's page cache.
_SQLITE_MMAP = 1 << 30


def read_sqlite(file: Path, topics: Sequence[str], collectors):
    """Deliver the payloads of ``topics`` in ``file`` to ``collectors``; return present topics."""
    try:
        con = sqlite3.connect(f'file:{file}?immutable=1', uri=True, check_same_thread=False)
    except sqlite3.Error as err:
        raise BagError(f'{file}: cannot open sqlite3 storage: {err}') from err
    try:
        rows = [(tid, name, topic_type(typ, fmt)) for tid, name, typ, fmt in con.execute(
            'SELECT id, name, type, serialization_format FROM topics').fetchall()]
        present = {}
        for _, name, typ in rows:
            if present.setdefault(name, typ) != typ:
                raise BagError(f'{file}: topic {name} recorded with two types '
                               f'{present[name]} and {typ}')
        ids = {tid: (name, typ) for tid, name, typ in rows if name in topics}
        if ids:
            _read_sqlite_messages(con, file, ids, collectors)
    except sqlite3.Error as err:
        raise BagError(f'{file}: corrupt sqlite3 storage: {err}') from err
    finally:
        con.close()
    return present


def _read_sqlite_messages(con, file, ids, collectors):
    # One pass per batch: SQLite concatenates the payloads itself and lists (topic id, length)
    # packed in one integer and the timestamps as text, so Python never touches a row.  All
    # aggregates step over the same rows in the same order (an ascending rowid range scan),
    # which keeps them consistent and gives rosbag2's (timestamp, id) order after a stable
    # sort on timestamp.  Fewer, integer-only group_concats are the cheapest form found.
    query = (
        "SELECT CAST(group_concat(data, x'') AS BLOB), "
        "group_concat((topic_id << 32) + length(data), ' '), group_concat(timestamp, ' ') "
        f"FROM messages WHERE id >= ? AND id < ? AND topic_id IN ({','.join('?' * len(ids))})")
    con.execute(f'PRAGMA mmap_size = {_SQLITE_MMAP}')

    def fetch(first):
        """Return one batch's (blob, packed, stamps) and the first id of the next batch."""
        row = con.execute(query, (first, first + _SQLITE_BATCH, *ids)).fetchone()
        # ids are normally 1..n; jumping to the next existing id also copes with holes
        following = con.execute('SELECT min(id) FROM messages WHERE id >= ?',
                                (first + _SQLITE_BATCH,)).fetchone()[0]
        return row, following

    # SQLite releases the GIL while it scans: a worker runs the next batch's query while this
    # thread decodes the current one (only the worker touches the connection meanwhile).
    with ThreadPoolExecutor(max_workers=1) as pool:
        first = con.execute('SELECT min(id) FROM messages').fetchone()[0]
        upcoming = pool.submit(fetch, first) if first is not None else None
        while upcoming is not None:
            (blob, *columns), following = upcoming.result()
            upcoming = pool.submit(fetch, following) if following is not None else None
            if blob is not None:
                _deliver_sqlite(file, ids, collectors, blob, columns)


def _deliver_sqlite(file, ids, collectors, blob: bytes, columns) -> None:
    packed, stamp = (np.fromstring(c, np.int64, sep=' ') for c in columns)
    lengths = packed & 0xFFFFFFFF
    if packed.size != stamp.size or lengths.sum() != len(blob):
        raise BagError(f'{file}: corrupt sqlite3 storage: payload lengths do not add up')
    table = np.stack([packed >> 32, stamp, lengths], axis=1)
    buf = np.frombuffer(blob, np.uint8)
    offsets = np.concatenate(([0], np.cumsum(table[:, 2])[:-1]))
    for tid, (name, typ) in ids.items():
        sel = np.flatnonzero(table[:, 0] == tid)
        if sel.size:
            collectors.sink(name, typ).add(table[sel, 1], table[sel, 2], buf, offsets[sel])
