"""Where a problem is in a model file.

One job: :class:`ModelFileError` and finding it a place. :class:`_Locator` finds the line of a
key path (``particles[1].position[0]``), and of a token within its value, in the raw TOML
text, best effort; :func:`_format_key` writes the key path.
"""

from __future__ import annotations

import json
import re
from typing import Sequence, Union

from ..errors import ModelError

_Key = Union[str, int]
_HEADER = re.compile(r"^\s*(\[\[?)\s*([A-Za-z_][\w.\s-]*?)\s*\]\]?\s*(#.*)?$")
_ASSIGNMENT = re.compile(r"^\s*[\w\"'.-]+\s*=")


class ModelFileError(ModelError):
    """A problem in a model file. ``filename``, ``line`` (or None), ``key`` and ``token`` say where."""

    def __init__(self, message: str, filename: str, line: int | None, key: str, token: str | None):
        self.filename = filename
        self.line = line
        self.key = key
        self.token = token
        where = f"{filename}:{line}" if line else filename
        super().__init__(message, location=f"{where}: {key}" if key else where)


def _format_key(path: Sequence[_Key]) -> str:
    out = ""
    for part in path:
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            text = part if re.fullmatch(r"[A-Za-z0-9_-]+", part) else json.dumps(part)
            out += f".{text}" if out else text
    return out


class _Locator:
    """Finds the line of a key path (and a value in it) in the raw TOML text, best effort."""

    def __init__(self, text: str, filename: str):
        self.filename = filename
        self.lines = text.splitlines()
        self.headers: list[tuple[int, bool, str]] = []  # (line index, array of tables?, name)
        for i, line in enumerate(self.lines):
            m = _HEADER.match(line)
            if m:
                self.headers.append((i, m.group(1) == "[[", re.sub(r"\s+", "", m.group(2))))

    def error(self, path: Sequence[_Key], message: str, needle: str | None = None,
              token: str | None = None) -> ModelFileError:
        """A located error: ``needle`` is text to look for (default ``token``)."""
        line = self.line(path, needle if needle is not None else token)
        return ModelFileError(message, self.filename, line, _format_key(path), token)

    def _section(self, path: Sequence[_Key]) -> tuple[int, int, list[str]] | None:
        """(first line, end line, keys left) of the table that holds ``path``."""
        if not path:
            return None
        # An array of tables ([[particles]], [[constraints.nonholonomic]]): its k-th header.
        k = next((i for i, part in enumerate(path) if not isinstance(part, str)), len(path))
        arrays = [i for i, is_array, name in self.headers if is_array and name == ".".join(map(str, path[:k]))]
        if 0 < k < len(path) and arrays:
            if path[k] >= len(arrays):
                return None
            start, rest = arrays[path[k]], path[k + 1:]
        else:
            names = []
            for part in path:
                if not isinstance(part, str):
                    break
                names.append(part)
            start = None
            for k in range(len(names), 0, -1):
                dotted = ".".join(names[:k])
                found = [i for i, is_array, name in self.headers if not is_array and name == dotted]
                if found:
                    start, rest = found[0], path[k:]
                    break
            if start is None:
                return None
        end = next((i for i, _, _ in self.headers if i > start), len(self.lines))
        return start, end, list(rest)

    def line(self, path: Sequence[_Key], needle: str | None = None) -> int | None:
        """1-based line number of ``path`` (and of ``needle`` within its value), or None."""
        section = self._section(path)
        if section is None:
            return self._find(needle, 0, len(self.lines)) if needle else None
        start, end, keys = section
        pos = start
        k = 0
        while k < len(keys):
            key = keys[k]
            if isinstance(key, int):
                # Element `key` of an inline array of tables: the (key+1)-th line with the next key.
                if k + 1 >= len(keys) or not isinstance(keys[k + 1], str):
                    break
                pattern = self._key_pattern(keys[k + 1])
                hits = [i for i in range(pos, end) if pattern.search(self.lines[i])]
                if key >= len(hits):
                    break
                pos = hits[key]
                k += 2
                continue
            pattern = self._key_pattern(key)
            hit = next((i for i in range(pos, end) if pattern.search(self.lines[i])), None)
            if hit is None:
                break
            pos = hit
            k += 1
        if needle:
            stop = next((i for i in range(pos + 1, end) if _ASSIGNMENT.match(self.lines[i])), end)
            hit = self._find(needle, pos, stop)
            if hit is not None:
                return hit
        return pos + 1

    @staticmethod
    def _key_pattern(key: str) -> re.Pattern:
        return re.compile(r"(?:^|[\s{,.])[\"']?" + re.escape(key) + r"[\"']?\s*=")

    def _find(self, needle: str, start: int, stop: int) -> int | None:
        for candidate in (f'"{needle}"', f"'{needle}'", needle):
            for i in range(start, stop):
                if candidate in self.lines[i]:
                    return i + 1
        return None
