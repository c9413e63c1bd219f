# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Write a rosbag2 sqlite3 storage file in bulk.

Same tables, columns and index as rosbags' ``Sqlite3Writer`` (rosbag2 schema version 4, with
the ``metadata`` table rosbag2 version 8 fills and ``message_definitions``).  Messages are
inserted by SQLite itself: per batch of samples one ``INSERT ... SELECT`` cuts every payload
out of one blob (``substr``) and takes the timestamps from a JSON array (``json_each``), so
Python binds three values per batch instead of three per message (about 3x faster than
``executemany``, which stays as the fallback for SQLite builds without JSON).  Row ids are
given explicitly, so the rosbag2 order (timestamp, id) never depends on the query plan.

The file is new and is deleted by the caller on any error, so the rollback journal is off and
syncing is left to the OS, as rosbag2's own non-resilient writing preset does.

``plan`` is :class:`.plan.BagPlan` (duck-typed here to keep the import one-way).
"""
from pathlib import Path
import sqlite3

import numpy as np

SQLITE_SCHEMA = """
CREATE TABLE schema(
  schema_version INTEGER PRIMARY KEY,
  ros_distro TEXT NOT NULL
);
CREATE TABLE metadata(
  id INTEGER PRIMARY KEY,
  metadata_version INTEGER NOT NULL,
  metadata TEXT NOT NULL
);
CREATE TABLE topics(
  id INTEGER PRIMARY KEY,
  name TEXT NOT NULL,
  type TEXT NOT NULL,
  serialization_format TEXT NOT NULL,
  offered_qos_profiles TEXT NOT NULL,
  type_description_hash TEXT NOT NULL
);
CREATE TABLE message_definitions(
  id INTEGER PRIMARY KEY,
  topic_type TEXT NOT NULL,
  encoding TEXT NOT NULL,
  encoded_message_definition TEXT NOT NULL,
  type_description_hash TEXT NOT NULL
);
CREATE TABLE messages(
  id INTEGER PRIMARY KEY,
  topic_id INTEGER NOT NULL,
  timestamp INTEGER NOT NULL,
  data BLOB NOT NULL
);
CREATE INDEX timestamp_idx ON messages (timestamp ASC);
"""
SCHEMA_VERSION = 4
ROS_DISTRO = 'rosbags'  # what rosbags' Writer records
SERIALIZATION_FORMAT = 'cdr'
DEFINITION_ENCODING = 'ros2msg'
# Payload bytes per INSERT: big enough to amortise the statement, small enough for the cache.
BATCH_BYTES = 2 << 20
# Larger pages cut B-tree overhead per row (~20 % faster inserts); readers do not care.
PAGE_SIZE = 16384

_INSERT_ONE = 'INSERT INTO messages (id, topic_id, timestamp, data) VALUES (?, ?, ?, ?)'


def write_sqlite(file: Path, plan, version: int, metadata_text: str,
                 use_json: bool = True) -> None:
    """
    Write ``plan`` as a new rosbag2 sqlite3 database (refused if the file exists).

    Parameters
    ----------
    file : pathlib.Path
        The ``.db3`` file.
    plan : BagPlan
        Connections and messages.
    version : int
        rosbag2 version, stored with ``metadata_text`` in the ``metadata`` table.
    metadata_text : str
        ``rosbag2_bagfile_information`` YAML.
    use_json : bool
        Insert with ``json_each`` when SQLite has it (False forces ``executemany``).

    Raises
    ------
    FileExistsError
        The file exists.
    sqlite3.Error, OSError
        The database cannot be written.

    """
    file.open('xb').close()  # refuse to overwrite, like rosbags' mcap writer
    con = sqlite3.connect(str(file), isolation_level=None)
    try:
        con.execute(f'PRAGMA page_size = {PAGE_SIZE}')
        con.execute('PRAGMA journal_mode = OFF')
        con.execute('PRAGMA synchronous = OFF')
        con.execute('BEGIN')
        for statement in SQLITE_SCHEMA.split(';'):
            if statement.strip():
                con.execute(statement)
        con.execute('INSERT INTO schema(schema_version, ros_distro) VALUES (?, ?)',
                    (SCHEMA_VERSION, ROS_DISTRO))
        seen = set()
        for cid, conn in enumerate(plan.connections, start=1):
            if conn.msgtype not in seen:
                seen.add(conn.msgtype)
                con.execute('INSERT INTO message_definitions (topic_type, encoding, '
                            'encoded_message_definition, type_description_hash) '
                            'VALUES (?, ?, ?, ?)',
                            (conn.msgtype, DEFINITION_ENCODING, conn.msgdef, conn.rihs01))
            con.execute('INSERT INTO topics VALUES (?, ?, ?, ?, ?, ?)',
                        (cid, conn.topic, conn.msgtype, SERIALIZATION_FORMAT, conn.qos,
                         conn.rihs01))
        _insert_messages(con, plan, use_json and _has_json(con))
        con.execute('INSERT INTO metadata(metadata_version, metadata) VALUES (?, ?)',
                    (version, metadata_text))
        con.execute('COMMIT')
        con.execute('PRAGMA optimize')
    finally:
        con.close()


def _has_json(con: sqlite3.Connection) -> bool:
    try:
        con.execute("SELECT count(*) FROM json_each('[1]')").fetchone()
    except sqlite3.OperationalError:
        return False
    return True


def _insert_messages(con: sqlite3.Connection, plan, use_json: bool) -> None:
    stamp = plan.stamp_ns
    n, n_dense = stamp.size, len(plan.dense)
    lengths = [topic.length for topic in plan.dense]
    columns = np.concatenate(([0], np.cumsum(lengths))).astype(int)
    width = int(columns[-1])
    rows = max(1, BATCH_BYTES // max(width, 1))
    block = np.zeros((min(rows, n), width), np.uint8)
    for k, topic in enumerate(plan.dense if n else ()):
        block[:, columns[k]:columns[k + 1]] = topic.template
    # batches end at sparse positions too, so sparse rows are inserted between batches
    bounds = np.union1d(np.r_[np.arange(0, n, rows), n], plan.sparse_at)
    sparse_order = iter(range(len(plan.sparse)))
    pending = next(sparse_order, None)
    next_id = 1
    insert = _json_insert(lengths, columns) if use_json else None
    for first, stop in zip(bounds, np.r_[bounds[1:], n]):
        first, stop = int(first), int(stop)
        while pending is not None and plan.sparse_at[pending] == first:
            index, t, payload = plan.sparse[pending]
            con.execute(_INSERT_ONE, (next_id, index + 1, t, payload))
            next_id += 1
            pending = next(sparse_order, None)
        if stop <= first or not n_dense:
            continue
        part = block[:stop - first]
        for k, topic in enumerate(plan.dense):
            topic.fill(part, int(columns[k]), first, stop)
        if use_json:
            stamps = '[' + ','.join(map(str, stamp[first:stop].tolist())) + ']'
            con.execute(insert, {'base': next_id, 'blob': memoryview(part).cast('B'),
                                 'stamps': stamps})
        else:
            con.executemany(_INSERT_ONE, _rows(part, stamp[first:stop], next_id, columns))
        next_id += (stop - first) * n_dense


def _json_insert(lengths, columns) -> str:
    """Return the INSERT that expands one batch (sample-major, topics in order)."""
    n_dense = len(lengths)
    width = int(columns[-1])
    topics = ', '.join(f'({k}, {k + 1}, {int(columns[k]) + 1}, {length})'
                       for k, length in enumerate(lengths))
    # CROSS JOIN keeps samples as the outer loop, so ids are also inserted in order (fast).
    return (
        f'WITH tk(k, topic_id, col, len) AS (VALUES {topics}) '
        'INSERT INTO messages (id, topic_id, timestamp, data) '
        f'SELECT :base + s.key * {n_dense} + tk.k, tk.topic_id, s.value, '
        f'substr(:blob, s.key * {width} + tk.col, tk.len) '
        'FROM json_each(:stamps) AS s CROSS JOIN tk')


def _rows(part: np.ndarray, stamp: np.ndarray, first_id: int, columns):
    data = memoryview(part).cast('B')
    width = int(columns[-1])
    pairs = list(zip(columns[:-1].tolist(), columns[1:].tolist()))
    row_id = first_id
    for j, t in enumerate(stamp.tolist()):
        base = j * width
        for k, (a, b) in enumerate(pairs):
            yield row_id, k + 1, t, data[base + a:base + b]
            row_id += 1
