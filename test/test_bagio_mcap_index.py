# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
MCAP summaries parsed in bulk (:mod:`.mcap_index`) agree with the one-record parsers.

Runs of equal records are located with numpy and the chunk indexes gathered as arrays; each
test compares with the record-by-record walk or parser on the same bytes, or damages a real
summary and checks the fault is named as before, with the file and the record's offset.
"""
import struct

import numpy as np
import pytest

from wheel_force_estimator.bagio import mcap_reader
from wheel_force_estimator.bagio import mcap_writer
from wheel_force_estimator.bagio import read_recording
from wheel_force_estimator.bagio import write_recording
from wheel_force_estimator.bagio.mcap_index import batches
from wheel_force_estimator.bagio.mcap_index import chunk_index_fields
from wheel_force_estimator.bagio.mcap_index import chunk_table
from wheel_force_estimator.bagio.mcap_index import ChunkTable
from wheel_force_estimator.bagio.mcap_index import locate
from wheel_force_estimator.bagio.mcap_index import OP_CHUNK_INDEX
from wheel_force_estimator.bagio.mcap_index import runs
from wheel_force_estimator.bagio.mcap_records import walk
from wheel_force_estimator.core.errors import BagError

PERIOD_NS = 1_953_125  # 512 Hz
N = 1500


class _Fault(Exception):
    pass


def _fail(what, at):
    return _Fault(what, at)


def _records(spec):
    """Concatenate records ``(opcode, body length)`` with recognisable bodies."""
    return b''.join(struct.pack('<BQ', op, n) + bytes([k % 251]) * n
                    for k, (op, n) in enumerate(spec))


@pytest.mark.parametrize('spec', [
    [],
    [(8, 40)],
    [(8, 40)] * 100,                                  # one long run (probes double)
    [(8, 40)] * 9 + [(8, 41)] + [(8, 40)] * 30,       # a run broken by one longer record
    [(3, 5), (4, 7)] * 20,                            # nothing repeats
    [(8, 0)] * 17 + [(11, 0)] * 3 + [(8, 0)] * 2,     # empty bodies
    [(7, 12)] * 8 + [(8, 12)] * 8,                    # same length, other opcode
])
def test_locate_equals_walk(spec):
    data = _records(spec)
    expected = list(walk(data, 0, len(data), _fail))
    op, body, length = locate(np.frombuffer(data, np.uint8), 0, len(data), _fail)
    assert list(zip(op.tolist(), body.tolist(), length.tolist())) == expected
    assert len(expected) == len(spec)


@pytest.mark.parametrize('cut', [1, 5, 9, 30, 45])
def test_locate_names_a_cut_record_as_walk_does(cut):
    # the last record of a long run is cut short: the run must stop before it, and the
    # error names the same offset and fault as the one-by-one walk
    data = _records([(8, 40)] * 50)[:-cut]
    with pytest.raises(_Fault) as one_by_one:
        list(walk(data, 0, len(data), _fail))
    with pytest.raises(_Fault) as bulk:
        locate(np.frombuffer(data, np.uint8), 0, len(data), _fail)
    assert bulk.value.args == one_by_one.value.args
    assert bulk.value.args[1] == 49 * 49


def _chunk_index(start, length, channels, index_length, compression):
    offsets = b''.join(struct.pack('<HQ', c, start + length + 20 * c) for c in channels)
    name = compression.encode()
    body = (struct.pack('<QQQQI', 1, 2, start, length, len(offsets)) + offsets
            + struct.pack('<QI', index_length, len(name)) + name + struct.pack('<QQ', 3, 4))
    return struct.pack('<BQ', OP_CHUNK_INDEX, len(body)) + body


def test_chunk_table_equals_the_one_record_parser():
    rng = np.random.default_rng(7)
    data = b''.join(_chunk_index(int(rng.integers(0, 1 << 40)), int(rng.integers(1, 1 << 20)),
                                 sorted(rng.choice(9, int(rng.integers(0, 5)), replace=False)),
                                 int(rng.integers(0, 999)), ['zstd', 'lz4', ''][k % 3])
                    for k in range(40))
    buf = np.frombuffer(data, np.uint8)
    op, body, length = locate(buf, 0, buf.size, _fail)
    table = chunk_table(buf, body, length, _fail)
    assert len(table) == 40
    names = table.compression()
    for k in range(40):
        start, size, (pos, count), index_length, comp = chunk_index_fields(
            data, int(body[k]), int(body[k] + length[k]))
        assert (table.start[k], table.length[k], table.map_pos[k], table.map_count[k],
                table.index_length[k], names[k]) == (start, size, pos, count, index_length,
                                                     comp)


@pytest.mark.parametrize('damage, fault', [
    (lambda rec: rec[:41] + b'\x07' + rec[42:], 'message index offsets map of a bad length'),
    (lambda rec: rec[:-20] + b'\xff\xfe' + rec[-18:], "codec can't decode"),
    (lambda rec: rec[:-24] + struct.pack('<I', 99) + rec[-20:], 'compression name overruns'),
])
def test_chunk_table_names_the_first_bad_record(damage, fault):
    good = [_chunk_index(1000 * k, 900, [1, 2], 60, 'zstd') for k in range(12)]
    records = good[:5] + [damage(good[5])] + good[6:]
    data = b''.join(records)
    buf = np.frombuffer(data, np.uint8)
    _, body, length = locate(buf, 0, buf.size, _fail)
    with pytest.raises(_Fault, match=fault) as err:
        chunk_table(buf, body, length, _fail)
    assert err.value.args[0].startswith('unreadable summary (')
    assert err.value.args[1] == sum(len(r) for r in records[:5])


def _reference_batches(start, end, batch_bytes, max_skip):
    """Apply the batching rule chunk by chunk (the reader's loop before #18's item 4)."""
    out, batch, hi = [], [], 0
    for k, (s, e) in enumerate(zip(start, end)):
        if batch and (s - hi > max_skip or e - start[batch[0]] > batch_bytes):
            out.append((batch[0], k, start[batch[0]], hi))
            batch = []
        hi = e if not batch else max(hi, e)
        batch.append(k)
    if batch:
        out.append((batch[0], len(start), start[batch[0]], hi))
    return out


@pytest.mark.parametrize('seed', range(6))
def test_batches_follow_the_rule(seed):
    rng = np.random.default_rng(seed)
    n = 300
    length = rng.integers(1, 5000, n)
    length[rng.integers(0, n, 5)] = 40_000  # chunks larger than a batch
    gap = np.where(rng.random(n) < 0.05, rng.integers(2000, 9000, n), rng.integers(0, 50, n))
    start = np.cumsum(gap + np.concatenate(([0], length[:-1])))
    table = ChunkTable(start, length, np.zeros(n, np.int64), np.zeros(n, np.int64),
                       np.zeros(n, np.int64), np.zeros(n, np.int64), ('',))
    got = batches(table, 20_000, 1500)
    assert got == _reference_batches(start.tolist(), (start + length).tolist(), 20_000, 1500)
    assert len(got) > 10


def test_runs_of_one_compression():
    assert runs(np.array([0, 0, 1, 1, 1, 0, 2])) == [(0, 2), (2, 5), (5, 6), (6, 7)]
    assert runs(np.array([3])) == [(0, 1)]


@pytest.fixture()
def many_chunks(tmp_path, monkeypatch):
    """Write an mcap of ours in ~8 KiB chunks (hundreds of chunk indexes), small batches."""
    monkeypatch.setattr(mcap_writer, 'CHUNK_BYTES', 8 << 10)
    monkeypatch.setattr(mcap_reader, '_BATCH_BYTES', 20 << 10)
    rng = np.random.default_rng(11)
    stamp = 3_000_000_000 + PERIOD_NS * np.arange(N, dtype=np.int64)
    path = write_recording(tmp_path / 'bag', stamp, rng.standard_normal((12, N)),
                           rng.standard_normal((12, N)), storage='mcap', compression='zstd')
    data_file = next(path.glob('*.mcap'))
    raw = bytearray(data_file.read_bytes())
    (summary_start,) = struct.unpack_from('<Q', raw, len(raw) - 37 + 9)  # footer
    data = np.frombuffer(bytes(raw), np.uint8)
    op, body, length = locate(data, summary_start, len(raw) - 37, _fail)
    sel = op == OP_CHUNK_INDEX
    assert sel.sum() > 100
    return path, data_file, raw, body[sel] - 9, length[sel] + 9


def test_summary_out_of_file_order_reads_the_same(many_chunks):
    # Chunk indexes in any order: the reader sorts them by chunk offset.
    path, data_file, raw, at, size = many_chunks
    ref = read_recording(path)
    assert size[3] == size[40]  # equally long records: swapped in place
    a, b = int(at[3]), int(at[40])
    n = int(size[3])
    raw[a:a + n], raw[b:b + n] = raw[b:b + n], raw[a:a + n]
    data_file.write_bytes(bytes(raw))
    rec = read_recording(path)
    assert np.array_equal(rec.segments[0].accel_mps2.view(np.int64),
                          ref.segments[0].accel_mps2.view(np.int64))
    assert np.array_equal(rec.segments[0].force_n.view(np.int64),
                          ref.segments[0].force_n.view(np.int64))


def test_damaged_chunk_index_names_file_and_offset(many_chunks):
    path, data_file, raw, at, _ = many_chunks
    k = int(at[77])
    raw[k + 9 + 32] = 7  # offsets map length: not a whole number of entries
    data_file.write_bytes(bytes(raw))
    with pytest.raises(BagError, match=rf'{data_file}: corrupt or truncated mcap: unreadable '
                                       rf'summary \(message index offsets map of a bad length\)'
                                       rf' at offset {k}$'):
        read_recording(path)


def test_chunk_index_beyond_the_file_is_named(many_chunks):
    path, data_file, raw, at, _ = many_chunks
    k = int(at[50])
    struct.pack_into('<Q', raw, k + 9 + 16, 1 << 63)  # chunk start far beyond the file
    data_file.write_bytes(bytes(raw))
    with pytest.raises(BagError, match=rf'{data_file}: corrupt or truncated mcap: chunk '
                                       rf'beyond end of file at offset {1 << 63}'):
        read_recording(path)


def test_no_usable_message_index_reads_every_chunk_through_its_records(many_chunks):
    # every message index damaged (outside the chunk CRCs): all chunks read record by record
    path, data_file, raw, at, _ = many_chunks
    ref = read_recording(path)
    data = np.frombuffer(bytes(raw), np.uint8)
    op, body, _ = locate(data, 8, int(at[0]), _fail)
    assert (op == 0x07).sum() > 100
    for k in (body[op == 0x07] - 9).tolist():
        raw[k] = 0x7F  # an opcode no reader knows: skipped as the spec says
    data_file.write_bytes(bytes(raw))
    rec = read_recording(path)
    assert rec.n_bulk == ref.n_bulk == 8 * N
    assert np.array_equal(rec.segments[0].force_n.view(np.int64),
                          ref.segments[0].force_n.view(np.int64))
