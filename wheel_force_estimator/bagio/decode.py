# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Decode the needed topics of any bag: the bulk and the fallback paths behind :mod:`.reader`.

* bulk: rosbag2 storages (mcap, sqlite3, any compression) read topic-wise with
  :mod:`.storage`, the fixed-layout Imu / WrenchStamped payloads decoded with :mod:`.fastcdr`
  and travel JointStates with :mod:`.travel`;
* fallback (``bulk=False``, or mcap indexes that miss messages): the same storages read
  without indexes (mcap record by record) and every message deserialised by rosbags'
  typestore; ROS 1 bags go message by message through rosbags' ``AnyReader``.

Only the topics asked for are decoded; the others are listed as skipped.
"""
from dataclasses import dataclass
from dataclasses import field
import functools
from pathlib import Path
import sqlite3
import struct
from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np
from rosbags.highlevel import AnyReader
from rosbags.highlevel import AnyReaderError
from rosbags.rosbag1 import ReaderError as Reader1Error
from rosbags.rosbag2 import ReaderError as Reader2Error
from rosbags.serde import SerdeError
from rosbags.typesys import get_typestore
from rosbags.typesys import Stores
from rosbags.typesys import TypesysError

from wheel_force_estimator.bagio import travel as travel_io
from wheel_force_estimator.bagio.cdr import Layout
from wheel_force_estimator.bagio.fastcdr import extract
from wheel_force_estimator.bagio.fastcdr import LAYOUTS
from wheel_force_estimator.bagio.fastcdr import STRING_TYPE
from wheel_force_estimator.bagio.fastcdr import TopicDecoder
from wheel_force_estimator.bagio.fastpath import FastPathUnavailable
from wheel_force_estimator.bagio.storage import RawTopic
from wheel_force_estimator.bagio.storage import read_raw_topics
from wheel_force_estimator.core.errors import BagError

try:  # rosbags' sqlite3 backend; its errors are not rosbags errors
    from apsw import Error as _ApswError
except ImportError:  # pragma: no cover - apsw is a rosbags dependency
    _ApswError = sqlite3.Error

# Low-level failures a damaged file can provoke inside rosbags; re-raised as BagError.
_ROSBAGS_ERRORS = (AnyReaderError, Reader1Error, Reader2Error, SerdeError, TypesysError,
                   OSError, ValueError, KeyError, IndexError, struct.error, sqlite3.Error,
                   _ApswError, EOFError, OverflowError)


@functools.lru_cache(maxsize=1)
def jazzy_typestore():
    """Return the ROS 2 Jazzy typestore (``Stores.LATEST`` would be Kilted)."""
    return get_typestore(Stores.ROS2_JAZZY)


def _bag_error(path: Path, err: BaseException) -> BagError:
    return BagError(f'{path}: cannot read bag: {type(err).__name__}: {err}')


@dataclass
class Decoded:
    """Per-topic decode results (internal)."""

    stamp_ns: Dict[str, np.ndarray] = field(default_factory=dict)
    values: Dict[str, np.ndarray] = field(default_factory=dict)  # (n, 3); travel (n, 4)
    strings: Dict[str, List[Tuple[int, str]]] = field(default_factory=dict)
    n_bulk: int = 0
    n_messages: int = 0
    skipped: Tuple[Tuple[str, str], ...] = ()


def _skipped(present, wanted) -> Tuple[Tuple[str, str], ...]:
    return tuple((t, m) for t, m in sorted(present.items()) if t not in wanted)


def _check_wanted(path, present, required, optional):
    wanted = dict(required)
    for name, msgtype in optional.items():
        if name in present:
            wanted[name] = msgtype
    for name, msgtype in wanted.items():
        if name not in present:
            listing = ', '.join(f'{t} ({m})' for t, m in sorted(present.items()))
            raise BagError(f'{path}: topic {name} ({msgtype}) not found; topics present: '
                           f'{listing or "none"}')
        if present[name] != msgtype:
            raise BagError(f'{path}: topic {name} has type {present[name]}, expected {msgtype}')
    return wanted


class _StackedValues:
    """
    One (3k, n) array whose row triplets receive k topics' values as they are decoded.

    :func:`.align.stack_corners` then finds the corners already stacked and copies nothing
    (an hour of 12 channels is 177 MB).  A topic with another message count gets no rows.
    """

    def __init__(self, topics):
        self.topics = list(topics)
        self.array: Optional[np.ndarray] = None

    def rows(self, topic: str, n: int) -> Optional[np.ndarray]:
        """Return the (n, 3) view for ``topic``, or None if ``n`` differs from the others."""
        if self.array is None:
            self.array = np.empty((3 * len(self.topics), n))
        if self.array.shape[1] != n:
            return None
        k = self.topics.index(topic)
        return self.array[3 * k:3 * k + 3].T


def read_topics(path: Path, required: Dict[str, str], optional: Dict[str, str],
                bulk: bool = True, stacked: Sequence[Sequence[str]] = (),
                fields: Optional[Dict[str, object]] = None) -> Decoded:
    """
    Decode the given topics (name -> expected type) of any supported bag.

    ``stacked`` lists groups of required topics (e.g. the four Imu corners) whose values the
    bulk path decodes into one shared corner-stacked array.  ``fields`` chooses, per topic,
    another vector than the default one (a :class:`.cdr.Layout` of the same type, e.g. the
    Imu's angular velocity) or, for a JointState, a :class:`.travel.JointField`.
    """
    fields = dict(fields or {})

    def layout_of(topic, msgtype):
        chosen = fields.get(topic)
        return chosen if isinstance(chosen, Layout) else LAYOUTS.get(msgtype)
    if bulk and path.suffix != '.bag':
        store = jazzy_typestore()
        groups = [_StackedValues(t for t in group if t in required) for group in stacked]

        def make_sink(topic, msgtype):
            layout = layout_of(topic, msgtype)
            if layout is None:
                return None  # keep raw payloads (event strings)

            def deserialize(data):
                return _deserialize(path, topic, store, data, msgtype)

            def values_out(n):
                for group in groups:
                    if topic in group.topics:
                        return group.rows(topic, n)
                return None
            return TopicDecoder(layout, deserialize, values_out)

        try:
            present, raw = read_raw_topics(path, list(required) + list(optional), make_sink)
        except FastPathUnavailable:
            pass
        else:
            return _decode_raw(path, raw, _check_wanted(path, present, required, optional),
                               present, fields=fields)
    if path.suffix != '.bag':
        try:  # every message through rosbags' deserialiser; mcap read record by record
            present, raw = read_raw_topics(path, list(required) + list(optional), scan=True)
        except FastPathUnavailable:
            pass  # not a rosbag2 recording this package reads: rosbags' AnyReader
        else:
            return _decode_raw(path, raw, _check_wanted(path, present, required, optional),
                               present, bulk=False, fields=fields)
    try:
        reader = AnyReader([path], default_typestore=jazzy_typestore())
        reader.open()
    except _ROSBAGS_ERRORS as err:
        raise _bag_error(path, err) from err
    try:
        present = {name: info.msgtype for name, info in reader.topics.items()}
        wanted = _check_wanted(path, present, required, optional)
        out = _decode_generic(path, reader, wanted, fields)
        out.skipped = _skipped(present, wanted)
        return out
    finally:
        reader.close()


def _decode_raw(path, raw, wanted, present, bulk: bool = True, fields=None) -> Decoded:
    out = Decoded(skipped=_skipped(present, wanted))
    store = jazzy_typestore()
    fields = fields or {}
    for name, msgtype in wanted.items():
        which = fields.get(name)
        topic = raw.get(name)
        out.n_messages += topic.n if topic is not None else 0
        if msgtype == STRING_TYPE:
            texts = []
            if topic is not None:
                texts = [''] * topic.n
                for pos, rows in topic.groups:
                    for p, row in zip(pos, rows):
                        texts[p] = _deserialize(path, name, store, row.tobytes(), msgtype).data
                texts = list(zip(topic.log_time_ns.tolist(), texts))
            out.strings[name] = texts
        elif topic is None:
            out.stamp_ns[name] = np.zeros(0, np.int64)
            out.values[name] = np.zeros((0, 4 if msgtype == travel_io.TRAVEL_TYPE else 3))
        elif msgtype == travel_io.TRAVEL_TYPE:
            def deserialize(data, name=name, msgtype=msgtype):
                return _deserialize(path, name, store, data, msgtype)
            joint = which if isinstance(which, travel_io.JointField) else travel_io.JointField()
            if bulk:
                out.stamp_ns[name], out.values[name] = travel_io.decode_rows(
                    path, name, topic.groups, topic.n, deserialize,
                    lambda msg: store.serialize_cdr(msg, travel_io.TRAVEL_TYPE), joint)
            else:
                msgs = [None] * topic.n
                for pos, rows in topic.groups:
                    for p, row in zip(pos.tolist(), rows):
                        msgs[p] = deserialize(row.tobytes())
                out.stamp_ns[name], out.values[name] = travel_io.decode_messages(path, name, msgs,
                                                                                 joint)
        elif isinstance(topic, RawTopic):  # fallback path: message by message
            layout = which if isinstance(which, Layout) else LAYOUTS[msgtype]
            out.stamp_ns[name], out.values[name] = _deserialize_all(path, name, store, topic,
                                                                    msgtype, layout)
        else:
            out.stamp_ns[name] = topic.stamp_ns
            out.values[name] = topic.values
            out.n_bulk += topic.n_fast
    return out


def _deserialize_all(path, name, store, topic: RawTopic, msgtype: str, layout: Layout):
    stamp = np.empty(topic.n, np.int64)
    values = np.empty((topic.n, 3))
    for pos, rows in topic.groups:
        for p, row in zip(pos.tolist(), rows):
            stamp[p], values[p] = extract(layout, _deserialize(path, name, store, row.tobytes(),
                                                               msgtype))
    return stamp, values


def _deserialize(path, topic, store, data: bytes, msgtype: str):
    try:
        return store.deserialize_cdr(data, msgtype)
    except (SerdeError, struct.error, ValueError, IndexError, UnicodeDecodeError) as err:
        raise BagError(f'{path}: {topic}: undecodable {msgtype} message: {err}') from err


def _decode_generic(path, reader, wanted, fields) -> Decoded:
    out = Decoded()
    conns = [c for c in reader.connections if c.topic in wanted]
    stamps: Dict[str, list] = {name: [] for name in wanted}
    vals: Dict[str, list] = {name: [] for name in wanted}
    try:
        for conn, log_time, data in reader.messages(connections=conns):
            msg = reader.deserialize(data, conn.msgtype)
            msgtype = wanted[conn.topic]
            if msgtype == STRING_TYPE:
                stamps[conn.topic].append((log_time, msg.data))
            elif msgtype == travel_io.TRAVEL_TYPE:
                vals[conn.topic].append(msg)
                stamps[conn.topic].append(0)
            else:
                chosen = fields.get(conn.topic)
                stamp, vec = extract(chosen if isinstance(chosen, Layout) else LAYOUTS[msgtype],
                                     msg)
                stamps[conn.topic].append(stamp)
                vals[conn.topic].append(vec)
    except _ROSBAGS_ERRORS as err:
        raise _bag_error(path, err) from err
    for name, msgtype in wanted.items():
        expected = sum(c.msgcount for c in conns if c.topic == name)
        got = len(stamps[name])
        if got != expected:
            # rosbags matches rosbag2 connections on QoS too and can silently yield nothing
            raise BagError(f'{path}: {name}: the bag index lists {expected} messages but '
                           f'{got} could be read')
        out.n_messages += got
        if msgtype == STRING_TYPE:
            out.strings[name] = stamps[name]
        elif msgtype == travel_io.TRAVEL_TYPE:
            joint = fields.get(name)
            out.stamp_ns[name], out.values[name] = travel_io.decode_messages(
                path, name, vals[name],
                joint if isinstance(joint, travel_io.JointField) else travel_io.JointField())
        else:
            out.stamp_ns[name] = np.asarray(stamps[name], np.int64).reshape(-1)
            out.values[name] = np.asarray(vals[name], np.float64).reshape(-1, 3)
    return out
