# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""``wheel-force`` console script: one parser, one thin module per subcommand."""
import argparse
import importlib
import os
import sys
from typing import List, Optional

from wheel_force_estimator import __version__
from wheel_force_estimator.cli.common import UsageError
from wheel_force_estimator.cli.heap import keep_freed_memory
from wheel_force_estimator.core.errors import WheelForceError

SUBCOMMANDS = ('simulate', 'fit', 'predict', 'evaluate', 'diagnose', 'fleet', 'node',
               'replay')
#: One-shot numeric commands: freed memory stays in the process for reuse (:mod:`.heap`).
#: The node, replay and fleet (long-lived, or a client of workers) keep the default.
BATCH = ('simulate', 'fit', 'predict', 'evaluate', 'diagnose')
#: Exit code when the reader of stdout went away (``wheel-force evaluate ... | head``): what a
#: process killed by SIGPIPE reports to the shell.
EXIT_BROKEN_PIPE = 128 + 13


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
    try:
        try:
            return _run(argv)
        finally:
            # Output still buffered must fail here, not in the interpreter's exit.
            sys.stdout.flush()
    except BrokenPipeError:
        # Python ignores SIGPIPE; without this the interpreter's final flush of stdout
        # would print a traceback after the reader (head, less) has gone.
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return EXIT_BROKEN_PIPE


def _run(argv: Optional[List[str]]) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.subcommand in BATCH:
        keep_freed_memory()
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
