# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Every command the README and ``docs/`` show runs as written.

The commands are extracted from the Markdown (fenced blocks and inline code): each
``wheel-force COMMAND`` is run with ``--help`` and every option the page shows must be one the
command accepts; ``make`` targets, launch files and their ``name:=value`` arguments, ROS
executables and benchmark scripts (run with ``--help`` where they take options) must exist.
Tools that are not ours (``ros2 topic``, ``colcon``, ``pip``, …) are left alone.
"""
import argparse
import ast
import contextlib
import functools
import io
from pathlib import Path
import re
import subprocess
import sys

import pytest

from wheel_force_estimator.cli.main import build_parser
from wheel_force_estimator.cli.main import SUBCOMMANDS

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / 'README.md'] + sorted((ROOT / 'docs').glob('*.md'))
OPTION = re.compile(r'(?<![\w\-`])(--[a-z][a-z0-9\-]*|-[a-zA-Z])(?![\w\-])')
PROGRAMS = ('wheel-force ', 'python -m wheel_force_estimator ', 'make ', 'ros2 launch ',
            'ros2 run ', 'python bench/', 'python3 bench/', '.venv/bin/python bench/')


def _logical_lines(block):
    r"""Join a fenced block's continuation lines (``\`` or an indented ``[``/``-`` line)."""
    out = []
    for raw in block.splitlines():
        line = raw.split(' # ')[0].rstrip() if not raw.lstrip().startswith('#') else ''
        if not line.strip():
            continue
        continues = out and (out[-1].endswith('\\') or (
            raw[:1].isspace() and line.strip()[:1] in '[-'))
        if continues:
            out[-1] = out[-1].rstrip('\\').rstrip() + ' ' + line.strip()
        else:
            out.append(line.strip())
    return out


def _pipeline(command):
    """Split at ``&&``, ``|`` and ``;`` outside brackets (``[--sim … | --model M]`` stays)."""
    parts, depth, start = [], 0, 0
    for match in re.finditer(r'[\[\]]|\s(?:&&|\||;)\s', command):
        token = match.group()
        if token in '[]':
            depth += 1 if token == '[' else -1
        elif depth == 0:
            parts.append(command[start:match.start()])
            start = match.end()
    return parts + [command[start:]]


def _commands(page):
    """Return ``(page, command)`` for every command of ours shown on ``page``."""
    text = page.read_text()
    found = []
    for block in re.findall(r'^```[a-z]*\n(.*?)^```', text, flags=re.S | re.M):
        found += _logical_lines(block)
    prose = re.sub(r'^```.*?^```', '', text, flags=re.S | re.M)
    found += re.findall(r'`([^`\n]+)`', prose)
    commands = []
    for command in found:
        for part in _pipeline(command):
            part = re.sub(r'^(nice -n \d+ |cd \S+ )', '', part.strip())
            if part.startswith(PROGRAMS):
                commands.append(part)
    return [(page.relative_to(ROOT).as_posix(), c) for c in dict.fromkeys(commands)]


COMMANDS = [item for page in PAGES for item in _commands(page)]


@functools.lru_cache(maxsize=None)
def _help(subcommand):
    out = io.StringIO()
    with contextlib.redirect_stdout(out), pytest.raises(SystemExit) as stop:
        build_parser().parse_args([subcommand, '--help'])
    assert stop.value.code == 0
    return out.getvalue()


@functools.lru_cache(maxsize=None)
def _script_help(script):
    """Return ``(returncode, stdout, stderr)`` of ``script --help``, once per script."""
    # the pages show some benchmarks many times, and each start imports numpy and scipy
    proc = subprocess.run([sys.executable, str(script), '--help'], cwd=ROOT,
                          capture_output=True, text=True, timeout=120)
    return proc.returncode, proc.stdout, proc.stderr


def _makefile_targets():
    text = (ROOT / 'Makefile').read_text()
    return set(re.findall(r'^([a-z][\w\-]*):', text, flags=re.M))


def _launch_arguments(name):
    tree = ast.parse((ROOT / 'launch' / name).read_text())
    for node in ast.walk(tree):
        if isinstance(node, ast.Assign) and getattr(node.targets[0], 'id', '') == 'ARGUMENTS':
            return set(ast.literal_eval(node.value))
    raise AssertionError(f'launch/{name}: no ARGUMENTS table')


def _console_scripts():
    return set(re.findall(r"'([\w\-]+) = wheel_force_estimator", (ROOT / 'setup.py').read_text()))


def test_the_pages_show_commands():
    # An extraction that finds nothing would pass every check below.
    pages = {page for page, _ in COMMANDS}
    assert {'README.md', 'docs/cli.md'} <= pages
    shown = {c.split()[1] for _, c in COMMANDS if c.startswith('wheel-force ')}
    assert {'fit', 'evaluate', 'predict', 'diagnose', 'fleet'} <= shown


@pytest.mark.parametrize('page,command', COMMANDS, ids=[f'{p}: {c[:60]}' for p, c in COMMANDS])
def test_command_runs_as_written(page, command):
    words = command.split()
    if command.startswith(('wheel-force ', 'python -m wheel_force_estimator ')):
        args = words[1:] if words[0] == 'wheel-force' else words[3:]
        sub = args[0] if args else ''
        if sub in ('--help', '--version') or sub.isupper():  # `wheel-force COMMAND --help`
            return
        assert sub in SUBCOMMANDS, f'{page}: `{command}`: no command {sub!r}'
        text = _help(sub)
        for option in OPTION.findall(' '.join(args[1:])):
            assert re.search(rf'(?<![\w\-]){re.escape(option)}(?![\w\-])', text), \
                f'{page}: `{command}`: `wheel-force {sub}` has no option {option}'
    elif words[0] == 'make':
        for target in (w for w in words[1:] if '=' not in w):
            assert target in _makefile_targets(), f'{page}: `{command}`: no make target'
    elif words[:2] == ['ros2', 'launch']:
        assert words[2] == 'wheel_force_estimator', f'{page}: `{command}`'
        declared = _launch_arguments(words[3])
        for argument in (w.split(':=')[0] for w in words[4:] if ':=' in w):
            assert argument in declared, f'{page}: `{command}`: no launch argument {argument}'
    elif words[:2] == ['ros2', 'run']:
        assert words[2] == 'wheel_force_estimator' and words[3] in _console_scripts(), \
            f'{page}: `{command}`'
    else:  # a benchmark script
        script = ROOT / next(w for w in words if w.startswith('bench/'))
        assert script.is_file(), f'{page}: `{command}`: no {script.name}'
        options = OPTION.findall(' '.join(words[2:]))
        if 'argparse' not in script.read_text():  # `--help` would run the benchmark
            assert not options, f'{page}: `{command}`: {script.name} takes no options'
        else:
            returncode, stdout, stderr = _script_help(script)
            assert returncode == 0, f'{page}: `{command}`: {stderr[-500:]}'
            for option in options:
                assert option in stdout, f'{page}: `{command}`: no option {option}'


def test_cli_md_lists_every_option_of_every_command():
    # docs/cli.md is the reference: an option added to a parser but not documented fails here.
    text = (ROOT / 'docs' / 'cli.md').read_text()
    parser = build_parser()
    (commands,) = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    missing = [f'{name} {option}' for name, sub in commands.choices.items()
               for action in sub._actions for option in action.option_strings
               if option not in ('-h', '--help') and not re.search(
                   rf'(?<![\w\-]){re.escape(option)}(?![\w\-])', text)]
    assert not missing, f'docs/cli.md does not list: {missing}'
