# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
MCAP records read one by one: schemas, channels and the messages of a chunk or data section.

The MCAP specification makes summaries, chunk indexes and message indexes optional: a valid
file may have only the records themselves (unchunked, no summary), or chunks without message
indexes (``index_types=CHUNK``).  :mod:`.mcap_reader` uses the indexes when they are there
and consistent with the records they point at, and this module when they are not: it walks
the records in storage order, which is always possible and checks every record length.
"""
import struct
from typing import Callable, Dict, Iterator, List, Tuple

OP_SCHEMA = 0x03
OP_CHANNEL = 0x04
OP_MESSAGE = 0x05
OP_CHUNK = 0x06
OP_DATA_END = 0x0F
#: Message record body before the payload: channel(2) sequence(4) log_time(8) publish_time(8).
MESSAGE_BODY_MIN = 22
#: The only message encoding whose payloads are ROS 2 messages.
CDR = 'cdr'


def topic_type(schema_name: str, message_encoding: str) -> str:
    """
    Return the type a topic is listed with: the schema name, plus the encoding if not CDR.

    A channel of another encoding (protobuf, json, ...) is never decoded; naming its encoding
    in the type makes a needed topic recorded that way fail the type check with both named.
    """
    if message_encoding == CDR:
        return schema_name
    return f'{schema_name or "(no schema)"} ({message_encoding or "no"} encoding)'


def _string(data, pos: int) -> Tuple[str, int]:
    (n,) = struct.unpack_from('<I', data, pos)
    end = pos + 4 + n
    if end > len(data):
        raise struct.error('string overruns the record')
    return bytes(data[pos + 4:end]).decode(), end


class Registry:
    """Schemas and channels met so far: channel id to ``(topic, type)``."""

    def __init__(self):
        self.schemas: Dict[int, str] = {}
        self.channels: Dict[int, Tuple[str, str]] = {}
        self._pending: Dict[int, Tuple[int, str, str]] = {}

    def add(self, op: int, data, body: int) -> None:
        """Register a Schema or Channel record whose body starts at ``body``."""
        if op == OP_SCHEMA:
            (sid,) = struct.unpack_from('<H', data, body)
            name, _ = _string(data, body + 2)
            self.schemas[sid] = name
            for cid, (c_sid, topic, enc) in list(self._pending.items()):
                if c_sid == sid:
                    self.channels[cid] = (topic, topic_type(name, enc))
        elif op == OP_CHANNEL:
            cid, sid = struct.unpack_from('<HH', data, body)
            topic, pos = _string(data, body + 4)
            encoding, _ = _string(data, pos)
            self._pending[cid] = (sid, topic, encoding)
            self.channels[cid] = (topic, topic_type(self.schemas.get(sid, ''), encoding))


def walk(data, pos: int, end: int,
         fail: Callable[[str, int], Exception]) -> Iterator[Tuple[int, int, int]]:
    """
    Yield ``(opcode, body start, body length)`` of every record in ``data[pos:end]``.

    Raises
    ------
    BagError
        (from ``fail``) A record header or body that overruns ``end``.

    """
    unpack = struct.unpack_from
    while pos < end:
        if end - pos < 9:
            raise fail('record header cut off', pos)
        op, length = unpack('<BQ', data, pos)
        body = pos + 9
        if length > end - body:
            raise fail(f'record (opcode 0x{op:02x}) overruns its container', pos)
        yield op, body, length
        pos = body + length


def scan_messages(data, first: int, end: int, wanted: Callable[[int], bool],
                  registry: Registry, fail: Callable[[str, int], Exception]
                  ) -> Dict[int, Tuple[List[int], List[int]]]:
    """
    Find the Message records of wanted channels in ``data[first:end]`` (a chunk's records).

    Parameters
    ----------
    data : bytes-like
        Buffer holding the records.
    first, end : int
        Record range in ``data``.
    wanted : callable
        ``wanted(channel_id)`` says whether a channel's messages are collected.
    registry : Registry
        Receives the Schema and Channel records met on the way.
    fail : callable
        ``fail(what, offset_in_data)`` builds the error to raise.

    Returns
    -------
    dict
        Channel id to ``(log times, record offsets in data)``, in storage order.

    """
    found: Dict[int, Tuple[List[int], List[int]]] = {}
    unpack = struct.unpack_from
    for op, body, length in walk(data, first, end, fail):
        if op == OP_MESSAGE:
            if length < MESSAGE_BODY_MIN:
                raise fail('message record too short', body - 9)
            cid, _, log_time = unpack('<HIQ', data, body)
            if wanted(cid):
                times, offsets = found.setdefault(cid, ([], []))
                times.append(log_time)
                offsets.append(body - 9)
        elif op in (OP_SCHEMA, OP_CHANNEL):
            try:
                registry.add(op, data, body)
            except (struct.error, UnicodeDecodeError) as err:
                raise fail(f'unreadable schema/channel record ({err})', body - 9) from err
    return found
