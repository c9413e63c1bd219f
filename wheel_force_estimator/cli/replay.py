# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
``wheel-force replay BAG [--rate X] [--record OUT_BAG] [--config YAML]``.

Plays the recording's Imu topics with their original stamps at ``X`` times real time (like
``ros2 bag play``) and, with ``--record``, writes the node's outputs to a new rosbag2.
"""
import argparse

from wheel_force_estimator.cli.common import add_namespace_argument
from wheel_force_estimator.cli.common import topic_config


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Register ``replay``."""
    p = subparsers.add_parser(
        'replay', help='play a recording to the live node, optionally record its outputs',
        description='Publish the four spindle Imu topics of BAG with their header stamps at '
                    "RATE times real time; with --record, collect the node's wrench outputs "
                    'and write them (with the inputs) to OUT_BAG.')
    p.add_argument('bag', metavar='BAG', help='recording with the four spindle Imu topics')
    p.add_argument('--rate', type=float, default=1.0, metavar='X',
                   help='playback speed, multiple of real time (default 1)')
    p.add_argument('--record', metavar='OUT_BAG', help="new rosbag2 for the node's outputs")
    p.add_argument('--config', metavar='YAML', help='params file (topic names, frame ids)')
    add_namespace_argument(p)
    p.add_argument('--storage', choices=('mcap', 'sqlite3'), default='mcap',
                   help='storage of OUT_BAG (default mcap)')
    p.add_argument('--wait', type=float, default=5.0, metavar='S',
                   help='wait up to S seconds for the node before playing (default 5)')
    p.add_argument('--settle', type=float, default=2.0, metavar='S',
                   help='with --record: stop S seconds after the last output (default 2)')
    return p


def command(args: argparse.Namespace) -> int:
    """Run ``replay``; return the exit code."""
    from wheel_force_estimator.ros.replay import imu_frame_ids_from_config
    from wheel_force_estimator.ros.replay import replay_bag
    from wheel_force_estimator.ros.replay import ReplaySettings

    topics = topic_config(args)
    settings = ReplaySettings(rate=args.rate, topics=topics,
                              imu_frame_ids=imu_frame_ids_from_config(args.config),
                              record=args.record is not None, wait_subscribers_s=args.wait,
                              settle_s=args.settle)
    recording, result = replay_bag(args.bag, settings, args.record, args.storage)
    duration_s = sum(s.n_samples for s in recording.segments) / recording.fs_hz
    print(f'played {result.n_samples} samples ({duration_s:.1f} s of signal, '
          f'{len(recording.segments)} segment(s)) in {result.wall_s:.1f} s: '
          f'{duration_s / max(result.wall_s, 1e-9):.2f}x real time (asked {args.rate:g}x, '
          f'at most {result.max_behind_s * 1e3:.1f} ms behind schedule)')
    if settings.record:
        print(f'received {", ".join(map(str, result.output_counts))} output messages '
              f'(lf, rf, lr, rr); {result.output_stamp_ns.size} complete samples')
        if args.record:
            print(f'wrote {args.record} ({args.storage})')
        if result.damage is not None:
            for status in result.damage.status:
                values = {kv.key: kv.value for kv in status.values}
                print(f'  {status.name}: {status.message}; '
                      + ', '.join(f'{k}={values[k]}' for k in
                                  ('fx', 'fy', 'fz', 'damage_rate_per_s', 'samples')
                                  if k in values))
    return 0
