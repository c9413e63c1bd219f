# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Benchmark: bulk rosbag2 writer vs rosbags' per-message Writer, same messages, same run.

Writes 4 WrenchStamped topics at 512 Hz (``write_forces``, what ``wheel-force predict``
writes; default 250 000 samples = 1 M messages) as rosbag2 mcap and sqlite3 and measures
messages per second of

* the bulk writer (``write_forces``), mcap chunks uncompressed (default) and zstd, and
* the baseline: payloads CDR-encoded in bulk (``cdr.encode_wrench``) then handed to rosbags'
  ``Writer.write`` one message at a time (the writer before the bulk one),

checks both bags read back to the same forces, and prints the speed-up and the real-time
factor for 4 corners at 512 Hz (goal >= 2000x, i.e. >= 4.1 M msg/s).  Every timed run starts
after ``os.sync()`` and its bag is deleted after, so dirty page-cache state does not leak
from one run into the next; the best of ``--repeat`` runs is kept (shared machine).

Usage: ``.venv/bin/python bench/bench_writer.py [--samples N] [--repeat K]
[--storage mcap|sqlite3]``
"""
import argparse
import os
from pathlib import Path
import shutil
import sys
import tempfile
import time

import numpy as np
from rosbags.rosbag2 import StoragePlugin
from rosbags.rosbag2 import Writer

from wheel_force_estimator import CORNERS
from wheel_force_estimator.bagio import mcap_writer
from wheel_force_estimator.bagio import read_wrench_topics
from wheel_force_estimator.bagio import TopicConfig
from wheel_force_estimator.bagio import write_forces
from wheel_force_estimator.bagio import writer
from wheel_force_estimator.bagio.cdr import encode_wrench
from wheel_force_estimator.bagio.fastcdr import WRENCH
from wheel_force_estimator.bagio.reader import jazzy_typestore

FS_HZ = 512
PERIOD_NS = 1_953_125
T0_NS = 1_700_000_000 * 10**9


def per_message_writer(path: Path, stamp, force_n, topics, storage: str) -> None:
    """Write like the old writer: bulk CDR encoding, then rosbags' Writer per message."""
    store = jazzy_typestore()
    plugin = StoragePlugin.MCAP if storage == 'mcap' else StoragePlugin.SQLITE3

    with Writer(path, version=8, storage_plugin=plugin) as bag:
        conns, payloads = [], []
        for k, topic in enumerate(topics.output_topics):
            conns.append(bag.add_connection(topic, WRENCH.msgtype, typestore=store))
            payloads.append(encode_wrench(stamp, force_n[3 * k:3 * k + 3],
                                          topics.frame_ids[k]))
        for i, t in enumerate(stamp.tolist()):
            for conn, rows in zip(conns, payloads):
                bag.write(conn, t, rows[i])


def _zstd_mcap(file, plan, version, metadata_text, compression=''):
    """Write mcap with zstd chunks whatever compression the writer asks for."""
    mcap_writer.write_mcap(file, plan, version, metadata_text, 'zstd')


def _timed(run, path: Path, repeat: int) -> float:
    best = float('inf')
    for _ in range(repeat):
        if path.exists():
            shutil.rmtree(path)
        os.sync()
        t0 = time.perf_counter()
        run(path)
        best = min(best, time.perf_counter() - t0)
    return best


def main(argv=None) -> int:
    """Run the benchmark and print the figures."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--samples', type=int, default=250_000,
                        help='samples per topic (4 topics; default 250000 = 1 M messages)')
    parser.add_argument('--storage', choices=('mcap', 'sqlite3'), action='append',
                        help='storage(s) to test (default both)')
    parser.add_argument('--repeat', type=int, default=3, help='best of this many runs')
    args = parser.parse_args(argv)
    n = args.samples
    n_msgs = 4 * n
    topics = TopicConfig(frame_ids=tuple(f'{c}_virtual' for c in CORNERS))
    stamp = T0_NS + PERIOD_NS * np.arange(n, dtype=np.int64)
    force = 1e3 * np.random.default_rng(0).standard_normal((12, n))
    realtime = 4 * FS_HZ  # messages per second of recording

    def line(name, seconds, base=None):
        rate = n_msgs / seconds
        ratio = f'  {base / seconds:6.1f}x vs per-message' if base else ''
        print(f'  {name:<34} {seconds:7.3f} s  {rate / 1e6:6.2f} M msg/s  '
              f'{rate / realtime:7.0f}x real time{ratio}', flush=True)

    print(f'{n_msgs} WrenchStamped messages ({n} samples x 4 corners, '
          f'{n / FS_HZ:.0f} s at {FS_HZ} Hz), best of {args.repeat}')
    with tempfile.TemporaryDirectory(dir=os.environ.get('BENCH_TMP')) as tmp:
        tmp = Path(tmp)
        for storage in args.storage or ['mcap', 'sqlite3']:
            print(f'{storage}:')
            base = _timed(lambda p, s=storage: per_message_writer(p, stamp, force, topics, s),
                          tmp / 'base', max(1, args.repeat - 1))
            line('rosbags Writer per message', base)
            variants = [('bulk writer', None)]
            if storage == 'mcap':
                variants.append(('bulk writer, zstd chunks', _zstd_mcap))
            for name, storage_writer in variants:
                saved = writer.STORAGES[storage]
                if storage_writer is not None:  # bench only: swap the storage writer
                    writer.STORAGES[storage] = (saved[0], storage_writer)
                try:
                    bulk = _timed(lambda p, s=storage: write_forces(p, stamp, force, topics, s),
                                  tmp / 'bulk', args.repeat)
                    size = sum(f.stat().st_size for f in (tmp / 'bulk').iterdir())
                finally:
                    writer.STORAGES[storage] = saved
                line(f'{name} ({size / 1e6:.0f} MB)', bulk, base)
                got_stamp, got_force = read_wrench_topics(tmp / 'bulk', topics.output_topics)
                ref_stamp, ref_force = read_wrench_topics(tmp / 'base', topics.output_topics)
                if not (np.array_equal(got_stamp, ref_stamp)
                        and np.array_equal(got_force, ref_force)
                        and np.array_equal(got_force, force)):
                    print('  MISMATCH between bulk and per-message bags', file=sys.stderr)
                    return 1
                shutil.rmtree(tmp / 'bulk')
            shutil.rmtree(tmp / 'base')
    return 0


if __name__ == '__main__':
    sys.exit(main())
