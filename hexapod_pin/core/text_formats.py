"""Strict parsing of the text formats the library reads: YAML, JSON, TOML and CSV headers.

Every reader of the package (loops and effects descriptions, geometry files, motion and
waypoint files, calibration measurements) parses through here, so that each refuses the
same things the same way, with a :class:`~hexapod_pin.errors.DescriptionError` naming the
file (``source``), the key and its lines:

* a key written twice in one YAML mapping or JSON object (the plain parsers keep the
  last one silently; TOML refuses it itself), named with its lines;
* a column name given twice in a CSV header;
* numbers outside the range the API accepts (NaN, inf, beyond
  :data:`~hexapod_pin.core.checks.MAX_MAGNITUDE`: :func:`check_values`);
* malformed content (the parser's own message).

The text itself comes from :func:`hexapod_pin.core.description.read_text` (a missing
file, a folder or binary / non-UTF-8 content refused there).
"""

from __future__ import annotations

import json
import math
import re
import sys
from collections.abc import Sequence
from typing import Any

import numpy as np
import yaml

from ..errors import DescriptionError
from .checks import MAX_MAGNITUDE

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10 (tomli is declared for it in pyproject.toml)
    import tomli as tomllib


class _Duplicate(Exception):
    """A key given twice (raised inside a parser, turned into a DescriptionError)."""

    def __init__(self, key: str, lines: list[int]):
        super().__init__(key)
        self.key = key
        self.lines = lines


def _duplicate_error(source: str, exc: _Duplicate) -> DescriptionError:
    where = f" (lines {' and '.join(str(n) for n in exc.lines)})" if exc.lines else ""
    culprit = exc.key + (f" (line {exc.lines[-1]})" if exc.lines else "")
    return DescriptionError(source, f"{exc.key} is written twice{where}", culprit)


def _check_keys(node: yaml.Node, path: str) -> None:
    """Refuse a key written twice in any mapping under ``node`` (``path``: its dotted
    key path, naming the key in the error with its lines)."""
    if isinstance(node, yaml.SequenceNode):
        for k, item in enumerate(node.value):
            _check_keys(item, f"{path}[{k}]")
    if not isinstance(node, yaml.MappingNode):
        return
    seen: dict[str, int] = {}
    for key_node, value_node in node.value:
        name = f"{path}.{key_node.value}" if path else str(key_node.value)
        line = key_node.start_mark.line + 1
        if isinstance(key_node, yaml.ScalarNode) and key_node.value != "<<":
            if name in seen:
                raise _Duplicate(name, [seen[name], line])
            seen[name] = line
        _check_keys(value_node, name)


def load_yaml(text: str, source: str) -> Any:
    """The data of a YAML document (safe types only).

    Raises:
        DescriptionError: malformed YAML (culprit: ``line N`` where the parser says), or a
            key written twice in one mapping (the message names its dotted path, e.g.
            ``effects.joints.crank``, and both lines; culprit: ``path (line N)``).
    """
    loader = None
    try:
        loader = yaml.SafeLoader(text)
        node = loader.get_single_node()
        if node is None:
            return None
        _check_keys(node, "")
        return loader.construct_document(node)
    except _Duplicate as exc:
        raise _duplicate_error(source, exc) from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        culprit = f"line {mark.line + 1}" if mark is not None else None
        raise DescriptionError(source, f"malformed YAML: {exc}", culprit) from None
    finally:
        if loader is not None:
            loader.dispose()


def load_json(text: str, source: str) -> Any:
    """The data of a JSON document.

    Raises:
        DescriptionError: malformed JSON, or a key written twice in one object (naming it
            and the lines where it appears). (``NaN`` / ``Infinity`` are read as Python's
            json reads them; the readers check the values.)
    """
    def pairs(items: list[tuple[str, Any]]) -> dict:
        out: dict = {}
        for key, value in items:
            if key in out:
                raise _Duplicate(key, _json_key_lines(text, key))
            out[key] = value
        return out

    try:
        return json.loads(text, object_pairs_hook=pairs)
    except _Duplicate as exc:
        raise _duplicate_error(source, exc) from None
    except json.JSONDecodeError as exc:
        raise DescriptionError(source, f"malformed JSON: {exc}") from None
    except RecursionError:
        raise DescriptionError(source, "malformed JSON: nested too deeply") from None


def _json_key_lines(text: str, key: str) -> list[int]:
    """The lines (1-based) where ``"key":`` appears in a JSON text."""
    pattern = re.compile(re.escape(json.dumps(key)) + r"\s*:")
    return [text.count("\n", 0, m.start()) + 1 for m in pattern.finditer(text)]


def load_toml(text: str, source: str) -> dict:
    """The table of a TOML document (TOML itself refuses a key given twice).

    Raises:
        DescriptionError: malformed TOML; a key written twice named with its line.
    """
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        found = re.search(r"at line (\d+)", str(exc))
        line = int(found.group(1)) if found else 0
        lines = text.splitlines()
        key = lines[line - 1].split("=", 1)[0].strip() if 0 < line <= len(lines) else ""
        if "overwrite" in str(exc) and key:
            raise DescriptionError(source, f"{key} is written twice (line {line}): {exc}",
                                   f"{key} (line {line})") from None
        raise DescriptionError(source, f"malformed TOML: {exc}") from None


def load_structured(text: str, source: str, kind: str) -> Any:
    """:func:`load_toml`, :func:`load_json` or :func:`load_yaml` by ``kind`` ("toml",
    "json", "yaml" or "yml")."""
    if kind == "toml":
        return load_toml(text, source)
    if kind == "json":
        return load_json(text, source)
    return load_yaml(text, source)


def check_values(values: np.ndarray, source: str, culprit: str) -> None:
    """Refuse NaN / inf and magnitudes beyond
    :data:`~hexapod_pin.core.checks.MAX_MAGNITUDE` among numbers read from a file (the
    range the API accepts).

    Raises:
        DescriptionError: naming the file, ``culprit`` (the field or column) and the
            index of the first such value.
    """
    bad = ~(np.abs(values) <= MAX_MAGNITUDE)
    if bad.any():
        first = tuple(int(i) for i in np.argwhere(bad)[0])
        value = float(values[first])
        reason = "contains NaN or inf" if not math.isfinite(value) else \
            f"has a value beyond {MAX_MAGNITUDE:g} in magnitude ({value:g})"
        raise DescriptionError(source, f"{culprit} {reason} at index {list(first)}", culprit)


def check_columns(names: Sequence[str], source: str, line: int = 1) -> list[str]:
    """The column names of a CSV header, stripped, after checking that none is empty or
    given twice.

    Raises:
        DescriptionError: an empty column name, or a name given twice (naming it, the
            line and both columns).
    """
    stripped = [name.strip() for name in names]
    seen: dict[str, int] = {}
    for k, name in enumerate(stripped, 1):
        if not name:
            raise DescriptionError(source, f"line {line}: column {k} has no name")
        if name in seen:
            raise DescriptionError(source, f"line {line}: duplicate column {name!r} "
                                           f"(columns {seen[name]} and {k})", name)
        seen[name] = k
    return stripped
