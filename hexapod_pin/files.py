"""Text files of the library: geometry files in, any text out atomically.

* Geometry files: a TOML, YAML or JSON table of the fields of a geometry dataclass
  (:class:`~hexapod_pin.hexapod.geometry.HexapodGeometry` by default, any frozen
  dataclass of numbers and tuples of numbers otherwise), at the top level or under a
  ``geometry`` table, e.g. ``leg_length = 0.5``; ``FIELD=VALUE`` overrides (the
  command line's ``--set``) are applied on top. Units are those of the dataclass
  (SI: m, kg, N). An as-built hexapod adds a ``chains`` table (``[chains]`` in TOML,
  under ``geometry`` when the fields are) with the five arrays of
  :class:`~hexapod_pin.hexapod.geometry.ChainGeometry` (``line_points``,
  ``line_directions``, ``platform_joints`` as six rows of three numbers,
  ``sensor_offsets`` and ``leg_lengths`` as six numbers; m, world / platform frame).
  :func:`save_geometry` writes such a file (every number as its shortest exact
  decimal, so that loading it back gives the same geometry bit for bit).
* :func:`write_text_atomic`: a file is replaced in one step (a temporary file in
  the same folder, then ``os.replace``), so a reader never sees half a file.

Motion files (sampled platform motions) live in :mod:`hexapod_pin.motion`, which
writes through :func:`write_text_atomic`.
"""

from __future__ import annotations

import dataclasses
import json
import os
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import yaml

from .core.description import file_path, read_text, suggest
from .core.text_formats import load_structured
from .errors import DescriptionError, GeometryError, InputError
from .hexapod.geometry import CHAIN_FIELDS, ChainGeometry, HexapodGeometry

#: suffixes of geometry files
GEOMETRY_SUFFIXES = (".toml", ".yaml", ".yml", ".json")
#: the field names of the geometries a file may hold (for suggestions)
_GEOMETRY_FIELDS = frozenset(f.name for f in dataclasses.fields(HexapodGeometry))


def write_text_atomic(path: str | os.PathLike, text: str) -> Path:
    """Write UTF-8 text to ``path`` through a temporary file in the same folder.

    The file gets the permissions a plain ``open(path, "w")`` would give (``0o666``
    less the umask). Returns the path.

    Raises:
        ArgumentTypeError: ``path`` is not a path.
        InputError: the folder does not exist, or ``path`` is a folder.
        OSError: the file cannot be written (the temporary file is removed).
    """
    path = Path(file_path(path))
    if not path.parent.is_dir():
        raise InputError("path", str(path), "its folder does not exist")
    if path.is_dir():
        raise InputError("path", str(path), "is a folder, expected a file name")
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o666 & ~umask)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as handle:
            handle.write(text)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def load_geometry(path: str | os.PathLike | None = None,
                  overrides: Sequence[str] | None = None,
                  geometry_type: type = HexapodGeometry) -> Any:
    """A geometry from its defaults, a geometry file and ``FIELD=VALUE`` overrides.

    Args:
        path: TOML / YAML / JSON file of fields (see the module doc); None: defaults.
        overrides: ``"FIELD=VALUE"`` strings applied after the file; a tuple field
            takes comma- or space-separated numbers (``platform_inertia=0.004,0.004,0.008``).
        geometry_type: the dataclass to build (default :class:`HexapodGeometry`).

    Returns:
        ``geometry_type(**fields)``.

    Raises:
        MissingFileError: the file does not exist.
        DescriptionError: unreadable or malformed file, or a suffix other
            than .toml, .yaml, .yml, .json.
        InputError: an override without ``=``.
        GeometryError: an unknown field, a value that is not a number, or a value the
            geometry rejects.
    """
    fields: dict = {}
    if path is not None:
        fields.update(read_geometry_file(path))
    tuple_fields = _tuple_fields(geometry_type)
    for item in overrides or []:
        if "=" not in item:
            raise InputError("--set", item, "expected FIELD=VALUE")
        key, value = (s.strip() for s in item.split("=", 1))
        fields[key] = _override_value(key, value, tuple_fields.get(key))
    known = {f.name for f in dataclasses.fields(geometry_type)}
    unknown = sorted(set(fields) - known, key=str)
    if unknown:
        raise GeometryError(str(unknown[0]), fields[unknown[0]], "unknown field"
                            + suggest(str(unknown[0]), known)
                            + f"; known: {', '.join(sorted(known))}")
    for key in tuple_fields:
        if isinstance(fields.get(key), list):
            fields[key] = tuple(fields[key])
    if "chains" in fields and "chains" in known:
        fields["chains"] = _chains_of(fields["chains"])
    try:
        return geometry_type(**fields)
    except TypeError as exc:  # e.g. a field given as a table
        raise GeometryError("geometry", fields, str(exc)) from None


def _chains_of(table: Any) -> ChainGeometry:
    """The :class:`ChainGeometry` of a file's ``chains`` table."""
    names = [name for name, _ in CHAIN_FIELDS]
    if not isinstance(table, dict):
        raise GeometryError("chains", table, f"must be a table of {', '.join(names)}")
    wrong = sorted(set(table) ^ set(names))
    if wrong:
        raise GeometryError("chains", sorted(table),
                            f"needs exactly the arrays {', '.join(names)} (got or missing: "
                            f"{', '.join(wrong)})")
    return ChainGeometry(**{name: table[name] for name in names})


def geometry_table(geometry: Any) -> dict:
    """The fields of a geometry dataclass as a table of plain numbers, lists and (for an
    as-built hexapod) the ``chains`` table of nested lists; ``chains = None`` is left out."""
    table: dict = {}
    for f in dataclasses.fields(geometry):
        value = getattr(geometry, f.name)
        if value is None:
            continue
        if isinstance(value, ChainGeometry):
            table[f.name] = value.as_dict()
        elif isinstance(value, tuple):
            table[f.name] = [float(v) for v in value]
        else:
            table[f.name] = float(value)
    return table


def _toml_value(value: Any) -> str:
    if isinstance(value, list):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    return repr(float(value))


def save_geometry(geometry: Any, path: str | os.PathLike) -> Path:
    """Write a geometry file that :func:`load_geometry` reads back to an equal geometry.

    Args:
        geometry: a :class:`HexapodGeometry` (ideal or as built) or another geometry
            dataclass of numbers and tuples of numbers.
        path: the file; its suffix (.toml, .yaml, .yml, .json) chooses the format.

    Returns:
        the path.

    Raises:
        DescriptionError: another suffix.
        InputError: the folder does not exist.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in GEOMETRY_SUFFIXES:
        raise DescriptionError(str(path), "geometry file must be .toml, .yaml, .yml or .json")
    table = geometry_table(geometry)
    if suffix == ".json":
        text = json.dumps({"geometry": table}, indent=2) + "\n"
    elif suffix in (".yaml", ".yml"):
        text = yaml.safe_dump({"geometry": table}, sort_keys=False)
    else:
        lines = ["[geometry]"]
        lines += [f"{key} = {_toml_value(value)}" for key, value in table.items()
                  if not isinstance(value, dict)]
        for key, value in table.items():
            if isinstance(value, dict):
                lines += ["", f"[geometry.{key}]"]
                lines += [f"{name} = {_toml_value(rows)}" for name, rows in value.items()]
        text = "\n".join(lines) + "\n"
    return write_text_atomic(path, text)
def read_geometry_file(path: str | os.PathLike) -> dict:
    """The table of geometry fields in a TOML / YAML / JSON file (not yet checked).

    Raises:
        MissingFileError: the file does not exist.
        DescriptionError: unknown suffix, malformed content, or not a table.
    """
    path = Path(file_path(path))
    text = read_text(path, "geometry file")
    suffix = path.suffix.lower()
    if suffix not in GEOMETRY_SUFFIXES:
        raise DescriptionError(str(path), "geometry file must be .toml, .yaml, .yml or .json")
    data = load_structured(text, str(path), suffix[1:])
    if isinstance(data, dict) and isinstance(data.get("geometry"), dict):
        outside = [key for key in data if key != "geometry"]
        if outside:
            key = outside[0]
            raise DescriptionError(str(path), f"key {key!r} outside the [geometry] table"
                                   + suggest(str(key), data["geometry"].keys()
                                              | _GEOMETRY_FIELDS, cutoff=0.6), str(key))
        data = data["geometry"]
    if not isinstance(data, dict):
        raise DescriptionError(str(path), "expected a table of geometry fields")
    return data


def _tuple_fields(geometry_type: type) -> dict[str, int]:
    """Fields of the dataclass whose default is a tuple, with the tuple's length."""
    return {f.name: len(f.default) for f in dataclasses.fields(geometry_type)
            if isinstance(f.default, tuple)}


def _override_value(key: str, text: str, length: int | None) -> float | tuple[float, ...]:
    parts = text.replace(",", " ").split()
    try:
        values = tuple(float(p) for p in parts)
    except ValueError:
        raise GeometryError(key, text, "not a number") from None
    if length is None:
        if len(values) != 1:
            raise GeometryError(key, text, "expected one number")
        return values[0]
    if len(values) != length:
        raise GeometryError(key, text, f"expected {length} numbers")
    return values
