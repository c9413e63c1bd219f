# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""``wheel-force`` console script: one parser, one thin module per subcommand."""
import argparse
import importlib
import sys
from typing import List, Optional

from wheel_force_estimator import __version__
from wheel_force_estimator.cli.common import UsageError
from wheel_force_estimator.core.errors import WheelForceError

SUBCOMMANDS = ('simulate', 'fit', 'predict', 'evaluate', 'diagnose', 'node', 'replay')


def build_parser() -> argparse.ArgumentParser:
    """Return the argument parser with every available subcommand registered."""
    parser = argparse.ArgumentParser(
        prog='wheel-force',
        description='Virtual wheel force transducer: fit, predict, evaluate, diagnose.')
    parser.add_argument('--version', action='version', version=f'%(prog)s {__version__}')
    sub = parser.add_subparsers(dest='subcommand', metavar='COMMAND')
    sub.required = True
    for name in SUBCOMMANDS:
        try:
            module = importlib.import_module(f'wheel_force_estimator.cli.{name}')
        except ImportError as err:
            # a subcommand whose optional dependency is missing must not break the others
            if err.name and err.name.startswith('wheel_force_estimator.cli.'):
                continue
            raise
        sub_parser = module.add_parser(sub)
        sub_parser.set_defaults(_command=module.command)
    return parser


def main(argv: Optional[List[str]] = None) -> int:
    """Run ``wheel-force``; return the process exit code (0 ok, 1 user error, 2 usage)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args._command(args))
    except UsageError as err:
        print(f'wheel-force {args.subcommand}: error: {err}', file=sys.stderr)
        return 2
    except WheelForceError as err:
        print(f'wheel-force {args.subcommand}: error: {err}', file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(f'wheel-force {args.subcommand}: interrupted', file=sys.stderr)
        return 130


if __name__ == '__main__':
    sys.exit(main())
