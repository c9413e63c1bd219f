# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Bulk access to the raw message payloads of a rosbag2 recording (sqlite3 and mcap).

rosbags yields one ``(connection, timestamp, bytes)`` tuple per message, which caps a reader at
a few hundred thousand messages per second before any decoding.  Here payloads come out in
batches of numpy arrays: sqlite3 through aggregate queries over rowid ranges
(:mod:`.sqlite_reader`), mcap memory-mapped through its chunk and message indexes
(:mod:`.mcap_reader`).  This module reads metadata.yaml and dispatches.  Each batch is
handed to a per-topic sink as (buffer, payload starts, lengths), valid during the call: a raw
collector here, or a decoder (:class:`.fastcdr.TopicDecoder`) that reads only the fields it
needs in place.

Topics are matched by name (and type), as ``ros2 bag`` does; QoS profiles are not compared.
Only the requested topics are ever decoded: other topics, whatever their type or encoding,
are listed and skipped.  Compressed bags are read too: message compression by decompressing
each requested payload before its sink sees it, file compression by decompressing the
storage files into a temporary directory first.  An mcap file whose indexes miss messages
raises :class:`FastPathUnavailable` and the caller reads it again record by record
(``scan=True``).  Structural damage raises :class:`BagError` naming the file.
"""
import contextlib
from dataclasses import dataclass
from pathlib import Path
from pathlib import PurePath
import tempfile
from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np

from wheel_force_estimator.bagio.compression import DECOMPRESS
from wheel_force_estimator.bagio.fastcdr import gather_bytes
from wheel_force_estimator.bagio.fastpath import FastPathUnavailable
from wheel_force_estimator.bagio.mcap_reader import McapFile
from wheel_force_estimator.bagio.sqlite_reader import read_sqlite
from wheel_force_estimator.core.errors import BagError
import yaml


@dataclass(frozen=True)
class RawTopic:
    """
    All raw payloads of one topic, in (bag timestamp, storage) order.

    Attributes
    ----------
    msgtype : str
        Message type name.
    log_time_ns : numpy.ndarray, shape (n,), int64
        Bag (receive) timestamps.
    groups : tuple of (numpy.ndarray, numpy.ndarray)
        ``(positions, rows)`` per payload length: positions (k,) into the topic's message
        order and rows (k, L) uint8 payloads.

    """

    msgtype: str
    log_time_ns: np.ndarray
    groups: Tuple[Tuple[np.ndarray, np.ndarray], ...]

    @property
    def n(self) -> int:
        """Return the number of messages."""
        return len(self.log_time_ns)

    def payload(self, i: int) -> bytes:
        """Return the payload of message ``i`` (slow; for tests and small topics)."""
        for pos, rows in self.groups:
            hit = np.flatnonzero(pos == i)
            if hit.size:
                return rows[hit[0]].tobytes()
        raise IndexError(i)


@dataclass(frozen=True)
class BagLayout:
    """What metadata.yaml says about a rosbag2 directory (or a bare storage file)."""

    storage: str
    files: Tuple[Path, ...]
    topic_types: Dict[str, str]
    topic_counts: Dict[str, int]
    compression_mode: str = ''
    compression_format: str = ''


def bag_layout(path: Path) -> BagLayout:
    """
    Describe a rosbag2 directory or a bare ``.mcap`` / ``.db3`` file.

    Raises
    ------
    FastPathUnavailable
        Not a rosbag2 recording (ROS 1 bag) or a storage plugin other than mcap / sqlite3.
    BagError
        metadata.yaml is unreadable or lists files that are missing, or an unknown
        compression.

    """
    if path.is_file():
        storage = {'.mcap': 'mcap', '.db3': 'sqlite3'}.get(path.suffix)
        if storage is None:
            raise FastPathUnavailable(f'{path}: not a rosbag2 storage file')
        return BagLayout(storage, (path,), {}, {})
    meta_path = path / 'metadata.yaml'
    try:
        doc = yaml.safe_load(meta_path.read_text(encoding='utf-8'))
        info = doc['rosbag2_bagfile_information']
        storage = info['storage_identifier']
        files = tuple(path / PurePath(p).name for p in info['relative_file_paths'])
        mode = str(info.get('compression_mode') or '').lower()
        if mode == 'none':
            mode = ''
        fmt = str(info.get('compression_format') or '').lower()
        types, counts = {}, {}
        for entry in info.get('topics_with_message_count') or ():
            meta = entry['topic_metadata']
            types[meta['name']] = meta['type']
            counts[meta['name']] = counts.get(meta['name'], 0) + int(entry['message_count'])
    except (OSError, yaml.YAMLError, KeyError, TypeError, ValueError) as err:
        raise BagError(f'{path}: cannot read rosbag2 metadata.yaml: {err!r}') from err
    if mode not in ('', 'file', 'message'):
        raise BagError(f'{path}: unknown compression_mode {mode!r} in metadata.yaml '
                       "(rosbag2 writes 'none', 'file' or 'message')")
    if mode and fmt not in DECOMPRESS:
        raise BagError(f'{path}: cannot read compression_format {fmt!r} (readable: '
                       f'{", ".join(sorted(DECOMPRESS))})')
    if storage not in ('mcap', 'sqlite3'):
        raise FastPathUnavailable(f'{path}: storage {storage!r}')
    missing = [str(f) for f in files if not f.is_file()]
    if missing:
        raise BagError(f'{path}: storage files listed in metadata.yaml are missing: {missing}')
    return BagLayout(storage, files, types, counts, mode, fmt)


@contextlib.contextmanager
def _storage_files(layout: BagLayout):
    """Yield the storage files, decompressed into a temporary directory in file mode."""
    if layout.compression_mode != 'file':
        yield layout.files
        return
    decompress = DECOMPRESS[layout.compression_format]
    with tempfile.TemporaryDirectory(prefix='wheel_force_bag_') as tmp:
        files = []
        for file in layout.files:
            name = file.name
            suffix = '.' + layout.compression_format
            out = Path(tmp) / (name[:-len(suffix)] if name.endswith(suffix) else name)
            try:
                out.write_bytes(decompress(file.read_bytes()))
            except (ValueError, RuntimeError, OSError) as err:
                raise BagError(f'{file}: compressed storage file does not decompress '
                               f'({layout.compression_format}): {err}') from err
            files.append(out)
        yield tuple(files)


class _Decompressing:
    """Sink wrapper for message-compressed bags: each payload is decompressed on arrival."""

    def __init__(self, sink, fmt: str, where: str):
        self.sink = sink
        self.fmt = fmt
        self.where = where
        self._decompress = DECOMPRESS[fmt]

    def add(self, log_time, lengths, buf, starts, head=None):
        del head  # of the compressed payload: meaningless
        payloads = []
        for k, (start, length) in enumerate(zip(starts.tolist(), lengths.tolist())):
            try:
                payloads.append(self._decompress(buf[start:start + length].tobytes()))
            except (ValueError, RuntimeError, OSError) as err:
                raise BagError(f'{self.where}: message {k} of a batch does not decompress '
                               f'({self.fmt}): {err}') from err
        sizes = np.fromiter((len(p) for p in payloads), np.int64, len(payloads))
        data = np.frombuffer(b''.join(payloads), np.uint8)
        offsets = np.concatenate(([0], np.cumsum(sizes)[:-1])).astype(np.int64)
        self.sink.add(log_time, sizes, data, offsets)

    def finish(self):
        return self.sink.finish()


class _Collector:
    """Accumulates (log_time, length-grouped rows) batches of one topic across files/chunks."""

    def __init__(self, msgtype: str):
        self.msgtype = msgtype
        self.times: List[np.ndarray] = []
        self.rows: Dict[int, List[Tuple[int, np.ndarray, np.ndarray]]] = {}
        self.count = 0

    def add(self, log_time: np.ndarray, lengths: np.ndarray, buf: np.ndarray,
            starts: np.ndarray, head: Optional[np.ndarray] = None):
        """Add a batch: payload ``i`` is ``buf[starts[i]:starts[i] + lengths[i]]``."""
        del head  # raw payloads are kept whole
        for length in np.unique(lengths):
            idx = np.flatnonzero(lengths == length)
            self.rows.setdefault(int(length), []).append(
                (self.count, idx, gather_bytes(buf, starts[idx], int(length))))
        self.times.append(np.asarray(log_time, np.int64))
        self.count += len(log_time)

    def finish(self) -> RawTopic:
        times = np.concatenate(self.times) if self.times else np.zeros(0, np.int64)
        order = np.argsort(times, kind='stable')
        rank = np.empty_like(order)
        rank[order] = np.arange(len(order))
        groups = []
        for length in sorted(self.rows):
            parts = self.rows[length]
            pos = np.concatenate([base + idx for base, idx, _ in parts])
            rows = parts[0][2] if len(parts) == 1 else np.concatenate([r for _, _, r in parts])
            groups.append((rank[pos], rows))
        return RawTopic(self.msgtype, times[order], tuple(groups))


class _Sinks(dict):
    """Topic -> sink, created on first use (raw collector unless ``make_sink`` says else)."""

    def __init__(self, make_sink, expected_counts: Optional[Dict[str, int]] = None,
                 compression: str = '', where: str = ''):
        super().__init__()
        self.make_sink = make_sink
        self.expected_counts = expected_counts or {}
        self.compression = compression
        self.where = where

    def sink(self, topic: str, msgtype: str):
        if topic not in self:
            made = self.make_sink(topic, msgtype) if self.make_sink else None
            if made is not None and hasattr(made, 'reserve') and (
                    self.expected_counts.get(topic, 0) > 0):
                made.reserve(self.expected_counts[topic])
            made = made if made is not None else _Collector(msgtype)
            if self.compression:
                made = _Decompressing(made, self.compression, f'{self.where}: {topic}')
            self[topic] = made
        return self[topic]


def read_raw_topics(path: Path, topics: Sequence[str], make_sink=None, scan: bool = False):
    """
    Read every payload of the given topics of a rosbag2 recording in bulk.

    Parameters
    ----------
    path : pathlib.Path
        rosbag2 directory, or a bare ``.mcap`` / ``.db3`` file.
    topics : sequence of str
        Topic names; topics absent from the storage are absent from the result.
    make_sink : callable, optional
        ``make_sink(topic, msgtype)`` returns the object receiving that topic's batches
        (``add(log_time, lengths, buf, starts, head=None)`` with payload ``i`` at
        ``buf[starts[i]:starts[i] + lengths[i]]``, valid only during the call, optionally its
        first 16 bytes already gathered in ``head`` (k, 16), and
        ``finish()``; e.g. a decoder), or None to keep the raw payloads.
    scan : bool
        Read mcap files record by record, ignoring their indexes (the fallback path).

    Returns
    -------
    present : dict
        Every topic in the storage: name to message type (with its encoding if not CDR).
    raw : dict
        Requested topic name to :class:`RawTopic` (or the sink's ``finish()`` result).

    Raises
    ------
    FastPathUnavailable
        Use the generic reader for this recording.
    BagError
        Truncated or corrupt storage (file and offset named), or message counts that
        disagree with metadata.yaml.

    """
    layout = bag_layout(path)
    compression = layout.compression_format if layout.compression_mode == 'message' else ''
    collectors = _Sinks(make_sink, layout.topic_counts, compression, str(path))
    present: Dict[str, str] = {}
    with _storage_files(layout) as files:
        for file in files:
            if layout.storage == 'sqlite3':
                found = read_sqlite(file, topics, collectors)
            else:
                found = McapFile(file, scan=scan).read(topics, collectors)
            for name, msgtype in found.items():
                if present.setdefault(name, msgtype) != msgtype:
                    raise BagError(f'{path}: topic {name} recorded with two types '
                                   f'{present[name]} and {msgtype}')
    raw = {name: col.finish() for name, col in collectors.items()}
    for name in topics:
        if name in layout.topic_counts:
            got = raw[name].n if name in raw else 0
            if got != layout.topic_counts[name]:
                raise BagError(
                    f'{path}: metadata.yaml lists {layout.topic_counts[name]} messages on '
                    f'{name} but the storage holds {got}: truncated or inconsistent bag')
    return present, raw
