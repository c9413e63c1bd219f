# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
A small markdown report writer: headings, paragraphs, tables and images in one directory.

The report directory holds ``report.md`` and the PNG plots it links to with relative links, so
the directory can be moved, zipped or opened on GitHub as a whole.
"""
import os
from pathlib import Path
from typing import List

from wheel_force_estimator.core.errors import ConfigError


class ReportWriter:
    """
    Collect markdown blocks for one report directory and write them to a file.

    Parameters
    ----------
    directory : str or Path
        Report directory; created (with parents) when missing.

    Raises
    ------
    ConfigError
        ``directory`` exists and is not a directory, or cannot be created.

    """

    def __init__(self, directory):
        self._directory = Path(directory)
        if self._directory.exists() and not self._directory.is_dir():
            raise ConfigError(f'report directory {self._directory}: exists and is not a '
                              'directory')
        try:
            self._directory.mkdir(parents=True, exist_ok=True)
        except OSError as err:
            raise ConfigError(f'report directory {self._directory}: cannot create it '
                              f'({err.strerror})') from err
        self._blocks: List[str] = []

    @property
    def directory(self) -> Path:
        """Return the report directory."""
        return self._directory

    def path(self, name: str) -> Path:
        """Return ``directory / name`` for a file (e.g. a plot) that belongs to the report."""
        return self._directory / _plain_name(name)

    def heading(self, text: str, level: int = 2) -> None:
        """Append a heading of ``level`` 1-6."""
        if isinstance(level, bool) or level not in range(1, 7):
            raise ConfigError(f'heading level must be 1-6, got {level!r}')
        self._blocks.append(f'{"#" * level} {_one_line(text, "heading")}')

    def paragraph(self, text: str) -> None:
        """Append a paragraph of plain markdown text."""
        self._blocks.append(str(text).strip())

    def table(self, md: str) -> None:
        """Append a markdown table, e.g. from :mod:`report.tables` with ``markdown=True``."""
        self._blocks.append(str(md).strip())

    def code(self, text: str) -> None:
        """Append a fenced block of preformatted text (e.g. an aligned plain-text table)."""
        self._blocks.append(f'```text\n{str(text).strip()}\n```')

    def image(self, path, caption: str) -> None:
        """
        Append an image link relative to the report directory, with the caption below.

        Raises
        ------
        ConfigError
            The image file does not exist (a link to nothing misleads the reader).

        """
        image = Path(path)
        if not image.is_absolute() and not image.exists():
            image = self._directory / image
        if not image.is_file():
            raise ConfigError(f'report image {path}: file does not exist')
        rel = Path(os.path.relpath(image.resolve(), self._directory.resolve())).as_posix()
        target = f'<{rel}>' if any(c in rel for c in ' ()') else rel
        text = _one_line(caption, 'caption')
        self._blocks.append(f'![{text}]({target})\n\n*{text}*')

    def text(self) -> str:
        """Return the markdown collected so far."""
        return '\n\n'.join(self._blocks) + '\n'

    def write(self, name: str = 'report.md') -> Path:
        """Write the report into the directory (replacing an older one) and return its path."""
        out = self._directory / _plain_name(name)
        tmp = out.with_name(out.name + '.tmp')
        # Write then rename so a reader never sees a half-written report.
        tmp.write_text(self.text(), encoding='utf-8')
        os.replace(tmp, out)
        return out


def _plain_name(name: str) -> str:
    if not name or Path(name).name != name or name in ('.', '..'):
        raise ConfigError(f'report file name {name!r}: must be a plain file name')
    return name


def _one_line(text: str, what: str) -> str:
    value = ' '.join(str(text).split())
    if not value:
        raise ConfigError(f'report {what}: empty text')
    return value
