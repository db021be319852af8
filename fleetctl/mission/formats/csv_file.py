"""CSV (``.csv``, comma-separated, a header row first): tasks and obstacle vertices.

Header (names case-insensitive, in any order; other columns are ignored):

* geodetic: ``id,lat,lon[,alt]`` (``latitude``, ``lon``/``lng``/``longitude``, ``altitude`` are
  accepted too) with ``alt`` in the datum of the mission's ``origin.alt`` (z = alt - origin.alt),
  or ``height`` instead of ``alt`` for the height above the ground (the mission's z); neither = on
  the ground;
* local: ``id,x,y[,z]`` in ENU metres (no origin needed).

The ``id`` column is optional for tasks (ids are generated without it). For obstacles every row
is a vertex and the rows with the same ``id`` form one polygon, in file order (without an ``id``
column all rows are one polygon).
"""

from __future__ import annotations

import csv
import difflib
import math
from dataclasses import dataclass
from typing import Any

from fleetctl.mission.formats.common import FormatError, RawPoint, RawPolygon, Vec2, check_count, decode

_SYNONYMS = {"latitude": "lat", "lng": "lon", "long": "lon", "longitude": "lon", "altitude": "alt"}
_KNOWN = ("id", "lat", "lon", "alt", "height", "x", "y", "z")
_FORMS = "id,lat,lon[,alt] (or height) or id,x,y[,z] (ENU metres)"


def parse(raw: bytes) -> Any:
    """The file's bytes as the document :func:`points` and :func:`polygons` read."""
    return decode(raw)


@dataclass(frozen=True)
class _Row:
    line: int
    id: str | None
    values: dict[str, float]


def _header(names: list[str]) -> dict[str, int]:
    cols: dict[str, int] = {}
    for i, raw in enumerate(names):
        name = _SYNONYMS.get(raw.strip().lower(), raw.strip().lower())
        if name in cols:
            raise FormatError("line 1", f"column {name!r} appears twice in the header")
        if name not in _KNOWN:
            close = difflib.get_close_matches(name, _KNOWN, n=1, cutoff=0.75)
            if close:
                raise FormatError("line 1", f"unknown column {raw.strip()!r}: did you mean {close[0]!r}? "
                                            f"The header is {_FORMS}")
            continue
        cols[name] = i
    return cols


def _mode(cols: dict[str, int], names: list[str]) -> str:
    geo, local = {"lat", "lon"} <= cols.keys(), {"x", "y"} <= cols.keys()
    if geo and local:
        raise FormatError("line 1", "the header has both lat/lon and x/y columns; keep one kind")
    if not geo and not local:
        hint = ""
        if len(names) == 1 and (";" in names[0] or "\t" in names[0]):
            hint = " (the file seems to use ';' or tabs: separate the columns with commas)"
        missing = ("lat", "lon") if ("lat" in cols or "lon" in cols or "x" not in cols) else ("x", "y")
        absent = [m for m in missing if m not in cols]
        raise FormatError("line 1", f"missing column(s) {', '.join(absent)}: the header names "
                                    f"{', '.join(n.strip() for n in names) or 'nothing'}; "
                                    f"give {_FORMS}{hint}")
    if geo and "alt" in cols and "height" in cols:
        raise FormatError("line 1", "give either an alt or a height column, not both")
    return "geo" if geo else "local"


def _value(text: str, line: int, col: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise FormatError(f"line {line}", f"column {col}: {text.strip()!r:.40} is not a number") from None
    if not math.isfinite(v):
        raise FormatError(f"line {line}", f"column {col}: {text.strip()!r} is not a finite number")
    return v


def _rows(text: str) -> tuple[str, list[_Row]]:
    reader = csv.reader(text.splitlines())
    names = next(reader, None)
    if names is None:
        raise FormatError("line 1", f"the file is empty; the first line is the header {_FORMS}")
    cols = _header(names)
    mode = _mode(cols, names)
    rows: list[_Row] = []
    for fields in reader:
        if not any(f.strip() for f in fields):
            continue
        check_count(len(rows) + 1, "rows")
        line = reader.line_num
        if len(fields) != len(names):
            raise FormatError(f"line {line}",
                              f"{len(fields)} fields for the {len(names)} columns of the header")
        ident = fields[cols["id"]].strip() if "id" in cols else None
        values = {c: _value(fields[i], line, c) for c, i in cols.items() if c != "id" and fields[i].strip()}
        for need in ("lat", "lon") if mode == "geo" else ("x", "y"):
            if need not in values:
                raise FormatError(f"line {line}", f"column {need} is empty; every row needs a value there")
        rows.append(_Row(line, ident or None, values))
    return mode, rows


def points(text: str) -> tuple[list[RawPoint], None]:
    mode, rows = _rows(text)
    if not rows:
        raise FormatError("line 2", "no task rows after the header")
    out = []
    for r in rows:
        v, where = r.values, f"line {r.line}"
        if mode == "local":
            out.append(RawPoint(where, r.id, xyz=(v["x"], v["y"], v.get("z", 0.0))))
        else:
            out.append(RawPoint(where, r.id, v["lat"], v["lon"], alt=v.get("alt"), height=v.get("height")))
    return out, None


def polygons(text: str) -> list[RawPolygon]:
    mode, rows = _rows(text)
    if not rows:
        raise FormatError("line 2", "no vertex rows after the header")
    groups: dict[str | None, list[_Row]] = {}
    for r in rows:
        groups.setdefault(r.id, []).append(r)
    out = []
    for ident, grp in groups.items():
        where = f"lines {grp[0].line}-{grp[-1].line}" + (f" (id {ident!r})" if ident else "")
        pts: tuple[Vec2, ...]
        if mode == "local":
            pts = tuple((r.values["x"], r.values["y"]) for r in grp)
            out.append(RawPolygon(where, xy=pts))
        else:
            pts = tuple((r.values["lat"], r.values["lon"]) for r in grp)
            out.append(RawPolygon(where, latlon=pts))
    return out


__all__ = ["parse", "points", "polygons"]
