# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""``wheel-force simulate OUT_BAG``: drive the simulated instrumented car, write a rosbag2."""
import argparse
from pathlib import Path

from wheel_force_estimator.cli.common import add_namespace_argument
from wheel_force_estimator.cli.common import topic_config


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Register ``simulate``."""
    p = subparsers.add_parser(
        'simulate', help='simulate a proving-ground recording (spindle Imu + WFT, rosbag2)',
        description='Drive the simulated instrumented car (full vehicle, 512 Hz) over a '
                    'proving-ground course and write the four spindle Imu and four WFT topics '
                    'plus /proving_ground/event as a new rosbag2.  With --pair, OUT_BAG is a '
                    'directory receiving sim/ (nominal car), real/ (car with the --physics '
                    'effects, same roads and noise) and holdout/ (real car, other seed).')
    p.add_argument('out', metavar='OUT_BAG', help='new bag directory (a directory with --pair)')
    p.add_argument('--course', default='proving_ground', metavar='NAME',
                   help='proving_ground (default, ~10 min), flat, or a single event: '
                        'highway, belgian_block, cobblestone, washboard, pothole, '
                        'manhole_cover, railway_crossing, speed_bump, driveway, variant_wave, '
                        'twist, braking, slalom, figure_8, city_braking')
    p.add_argument('--physics', default='', metavar='NAME[,NAME...]',
                   help='physics effects of the car (DESIGN.md vocabulary, e.g. '
                        'bump_stop,time_delay); default: the nominal model')
    p.add_argument('--seed', type=int, default=0, metavar='N', help='roads and noise seed')
    p.add_argument('--duration-scale', type=float, default=1.0, metavar='X',
                   help='shorten (< 1) every event proportionally')
    p.add_argument('--storage', choices=('mcap', 'sqlite3'), default='mcap')
    p.add_argument('--pair', action='store_true',
                   help='write sim/, real/ and holdout/ into the OUT_BAG directory')
    p.add_argument('--holdout-seed', type=int, metavar='N',
                   help='seed of holdout/ with --pair (default: seed + 1)')
    p.add_argument('--fs-hz', type=float, default=512.0, metavar='HZ', help='sample rate')
    p.add_argument('--vehicle', metavar='YAML', help='vehicle parameter overrides')
    p.add_argument('--effect-params', metavar='YAML',
                   help='effect parameter overrides {effect: {param: value}}')
    p.add_argument('--config', metavar='YAML', help='params file (topic names)')
    p.add_argument('--travel', action='store_true',
                   help='also write the suspension compression (m, + in bump) as '
                        'sensor_msgs/JointState on suspension/joint_states (travel_topic), '
                        'as string potentiometers would record it')
    p.add_argument('--six', action='store_true',
                   help='six components: also write the wheel moments (N m, wrench.torque), '
                        'the spindle angular rates (rad/s, Imu.angular_velocity) and the wheel '
                        'spin rates (rad/s, velocity of the {corner}_wheel joints on '
                        'suspension/joint_states)')
    p.add_argument('--no-spin', dest='spin', action='store_false',
                   help='with --six: leave the wheel spin rates out (a logger without '
                        'wheel speeds)')
    add_namespace_argument(p)
    return p


def command(args: argparse.Namespace) -> int:
    """Run ``simulate``; return the exit code."""
    import numpy as np

    from wheel_force_estimator import MOMENT_CHANNELS
    from wheel_force_estimator import OUTPUT_CHANNELS
    from wheel_force_estimator.core.errors import BagError
    from wheel_force_estimator.sim.api import simulate
    from wheel_force_estimator.sim.api import simulate_pair
    from wheel_force_estimator.sim.api import write_result
    from wheel_force_estimator.sim.effects import load_effect_params
    from wheel_force_estimator.sim.effects import resolve_effects
    from wheel_force_estimator.sim.vehicle import load_vehicle

    vehicle = load_vehicle(args.vehicle) if args.vehicle else None
    effect_params = load_effect_params(args.effect_params) if args.effect_params else None
    effects = resolve_effects(args.physics, effect_params)
    topics = topic_config(args)
    physics = ', '.join(effects.names) or 'none (nominal)'
    if args.pair:
        paths = simulate_pair(args.out, effects.names, args.seed, args.holdout_seed,
                              args.duration_scale, args.storage, course=args.course,
                              vehicle=vehicle, effect_params=effect_params, fs_hz=args.fs_hz,
                              topics=topics, progress=True, travel=args.travel)
        print(f'course: {args.course}   physics of real/ and holdout/: {physics}')
        for name in ('sim', 'real', 'holdout', 'truth'):
            print(f'  {name:8s} {paths[name]}')
        return 0
    out = Path(args.out)
    if out.exists():
        raise BagError(f'{out}: exists already, not overwriting')
    result = simulate(args.course, effects.names, args.seed, args.duration_scale, args.fs_hz,
                      vehicle, effect_params, progress=True)
    write_result(out, result, args.storage, topics, travel=args.travel, six=args.six,
                 spin=args.spin)
    print(f'wrote {out} ({args.storage}): {result.stamp_ns.size} samples, '
          f'{result.duration_s:.1f} s at {result.fs_hz:g} Hz, {len(result.events)} events')
    print(f'course: {args.course}   seed: {args.seed}   physics: {physics}')
    rms = np.std(result.force_n, axis=1)
    print('dynamic force RMS [N]: ' + ', '.join(
        f'{c} {v:.0f}' for c, v in zip(OUTPUT_CHANNELS, rms)))
    if args.six:
        rms = np.std(result.moment_nm, axis=1)
        print('dynamic moment RMS [N m]: ' + ', '.join(
            f'{c} {v:.0f}' for c, v in zip(MOMENT_CHANNELS, rms)))
    return 0
