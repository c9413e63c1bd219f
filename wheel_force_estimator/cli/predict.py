# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""``wheel-force predict MODEL BAG -o OUT_BAG``: virtual WFT forces into a new rosbag2."""
import argparse

from wheel_force_estimator.cli.common import add_namespace_argument
from wheel_force_estimator.cli.common import topic_config


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Register ``predict``."""
    p = subparsers.add_parser(
        'predict', help='predict wheel forces from spindle accelerations into a new bag',
        description='Predict /virtual_wft/{corner}/wrench (static + dynamic force, input '
                    'stamps) for every sample of BAG and write them to a new rosbag2.')
    p.add_argument('model', metavar='MODEL', help='model file (.npz)')
    p.add_argument('bag', metavar='BAG', help='recording with the four spindle Imu topics')
    p.add_argument('-o', '--output', required=True, metavar='OUT_BAG', help='new rosbag2 dir')
    p.add_argument('--config', metavar='YAML', help='params file (topic names)')
    add_namespace_argument(p)
    p.add_argument('--storage', choices=('mcap', 'sqlite3'),
                   help='storage of OUT_BAG (default: same as BAG; mcap for ROS 1 input)')
    p.add_argument('--compression', choices=('zstd', 'none'), default='zstd',
                   help='mcap chunk compression of OUT_BAG (default zstd: ~30 %% of the size, '
                        'read by ros2 bag and rosbags; ignored for sqlite3)')
    from wheel_force_estimator.cli.common import add_causal_arguments
    add_causal_arguments(p, 'predict')
    return p


def command(args: argparse.Namespace) -> int:
    """Run ``predict``; return the exit code."""
    from wheel_force_estimator.bagio import write_recording
    from wheel_force_estimator.cli.common import check_bag_model
    from wheel_force_estimator.cli.common import read_recordings
    from wheel_force_estimator.cli.common import announce
    from wheel_force_estimator.cli.common import causal_delay
    from wheel_force_estimator.core.model import load_model
    import numpy as np

    from wheel_force_estimator import OUTPUT_CHANNELS
    from wheel_force_estimator.offline import bag_extras
    from wheel_force_estimator.offline import input_storage
    from wheel_force_estimator.offline import predict_recording
    from wheel_force_estimator.offline import split_loads
    from wheel_force_estimator.offline import stream_recording

    model = load_model(args.model)
    check_bag_model(model, args.model)
    delay = causal_delay(args, model.fs_hz)
    announce(model, args.model, delay)
    topics = topic_config(args)
    extras = bag_extras(model, args.model, with_wft=False)
    (recording,) = read_recordings([args.bag], topics, require_wft=False,
                                   expected_fs_hz=model.fs_hz, extras=extras)
    storage = args.storage or input_storage(args.bag)
    torque = None
    if len(model.output_channels) > len(OUTPUT_CHANNELS):
        # six components: forces and moments written together (not streamed)
        parts = predict_recording(model, recording, delay)
        stamps = np.concatenate([p[0] for p in parts])
        force, torque = split_loads(np.concatenate([p[1] for p in parts], axis=1))
    else:
        stamps, force = stream_recording(model, recording, delay)
    write_recording(args.output, stamps, force_n=force, topics=topics, storage=storage,
                    output=True, compression=args.compression.replace('none', ''),
                    torque_nm=torque)
    print(f'predicted {stamps.size} samples in {len(recording.segments)} segment(s) of '
          f'{args.bag} -> {args.output} ({storage})')
    return 0
