"""Reading an ESRI ASCII grid (``.asc``): a header of ``key value`` lines (``ncols``,
``nrows``, ``cellsize``, the lower-left corner or centre, ``NODATA_value``), then ``nrows``
rows of ``ncols`` numbers, north to south.

A malformed file is refused with :class:`GridFileError`, whose text names the file, the line
and what is wrong there. Rows that wrap over several lines are read as GDAL reads them, as one
stream of ``nrows x ncols`` numbers.

The format itself has no coordinate system: a ``.prj`` file beside the grid (same name) gives
it, as ESRI and GDAL write it (:func:`projection_file`; :mod:`sitl.terrain.files` then reads
the grid through GDAL, which takes the ``.prj``). Without one, the grid is in metres.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import NamedTuple, TextIO

import numpy as np

from sitl.terrain.file_errors import GridFileError

HEADER_KEYS = {
    "ncols": "ncols",
    "nrows": "nrows",
    "xllcorner": "xllcorner",
    "yllcorner": "yllcorner",
    "xllcenter": "xllcenter",
    "yllcenter": "yllcenter",
    "cellsize": "cellsize",
    "nodata_value": "NODATA_value",
}  # lower case -> as the format spells it
REQUIRED = ("ncols", "nrows", "cellsize")
WHOLE = ("ncols", "nrows")


class AsciiGrid(NamedTuple):
    """An ESRI ASCII grid as read: heights north-up (nrows, ncols) float64, the cell size,
    NODATA_value (None when not given) and the lower-left corner (x, y) of the grid (of its
    corner cell's corner, whether the header gives the corner or the centre)."""

    heights: np.ndarray
    cell: float
    nodata: float | None
    corner: tuple[float, float]


def projection_file(path: Path) -> Path | None:
    """The ``.prj`` file beside ``path`` (same name; ``.prj`` or ``.PRJ``), or None."""
    for suffix in (".prj", ".PRJ"):
        prj = path.with_suffix(suffix)
        if prj.is_file():
            return prj
    return None


def looks_geographic(grid: AsciiGrid) -> bool:
    """True for a grid whose cell size (under 1 cm) and corner (a longitude and latitude,
    not the origin) say degrees rather than metres: 1 and 3 arc-seconds are 2.8e-4 and
    8.3e-4, 30 arc-seconds 8.3e-3."""
    x, y = grid.corner
    return grid.cell < 0.01 and abs(x) <= 180 and abs(y) <= 90 and (x, y) != (0.0, 0.0)


def read_asc(path: Path) -> AsciiGrid:
    """The grid of an ESRI ASCII file (:class:`AsciiGrid`); GridFileError on a malformed one."""
    with path.open(encoding="utf-8-sig") as f:
        try:
            header, first_data_line = _header(path, f)
            shape = (header["nrows"], header["ncols"])
            start = f.tell()
            try:
                values = np.loadtxt(f, dtype=np.float64, ndmin=2)
            except ValueError:  # a word or a ragged row: found with its line below
                values = None
            if values is None or values.size != shape[0] * shape[1]:
                f.seek(start)
                values = _values_or_reason(path, f, first_data_line, shape)
        except UnicodeDecodeError:
            raise GridFileError(f"{path}: not text (an ESRI ASCII grid is plain text)") from None
    cell = header["cellsize"]
    half = cell / 2  # a centre given instead of the corner
    corner = (header.get("xllcorner", header.get("xllcenter", half) - half),
              header.get("yllcorner", header.get("yllcenter", half) - half))
    return AsciiGrid(values.reshape(shape), cell, header.get("nodata_value"), corner)


def _header(path: Path, f: TextIO) -> tuple[dict, int]:
    """The header's values (ncols and nrows as int) and the number of the line after it."""
    header: dict = {}
    lineno = 0
    while True:
        pos = f.tell()
        line = f.readline()
        lineno += 1
        parts = line.split()
        if not line or (parts and _is_number(parts[0])):  # the first row of values
            f.seek(pos)
            break
        if not parts:
            continue
        where = f"{path}:{lineno}"
        key = parts[0].lower()
        if key not in HEADER_KEYS:
            raise GridFileError(f"{where}: {parts[0]!r} is not an ESRI ASCII header key "
                                f"({', '.join(HEADER_KEYS.values())})")
        if len(parts) != 2:
            raise GridFileError(f"{where}: header line {parts[0]} needs one value, "
                                f"found {len(parts) - 1}")
        if key in header:
            raise GridFileError(f"{where}: {parts[0]} given twice")
        if not _is_number(parts[1]):
            raise GridFileError(f"{where}: {parts[0]} {parts[1]!r} is not a number")
        value = float(parts[1])
        if key in WHOLE:
            if not math.isfinite(value) or value != int(value) or value < 1:
                raise GridFileError(f"{where}: {parts[0]} {parts[1]} is not a whole number "
                                    "of cells")
            value = int(value)
        header[key] = value
    for key in REQUIRED:
        if key not in header:
            raise GridFileError(f"{path}:{lineno}: the header lacks {key} before the values")
    return header, lineno


def _values_or_reason(path: Path, f: TextIO, first: int, shape: tuple[int, int]
                      ) -> np.ndarray:
    """The values of a file that did not load as ``shape``: as one stream if there are
    exactly enough (rows wrapped over lines), else GridFileError at the first bad line."""
    nrows, ncols = shape
    rows: list[np.ndarray] = []
    lines: list[int] = []  # the number of each line with values
    last = first - 1
    for last, line in enumerate(f, start=first):
        parts = line.split("#", 1)[0].split()  # np.loadtxt's comments, as on the fast path
        if not parts:
            continue
        try:
            rows.append(np.array(parts, dtype=np.float64))
        except ValueError:
            i, word = next((i, w) for i, w in enumerate(parts, 1) if not _is_number(w))
            raise GridFileError(f"{path}:{last}: value {i} of the row, {word!r}, is not a "
                                "number") from None
        lines.append(last)
    if sum(len(row) for row in rows) == nrows * ncols:
        return np.concatenate(rows)
    for number, row in zip(lines, rows, strict=True):
        if len(row) != ncols:
            raise GridFileError(f"{path}:{number}: {len(row)} values in the row, ncols says "
                                f"{ncols}")
    if len(rows) > nrows:
        raise GridFileError(f"{path}:{lines[nrows]}: more rows of values than nrows ({nrows})")
    raise GridFileError(f"{path}:{last}: the file ends after {len(rows)} row(s) of values, "
                        f"fewer than nrows ({nrows})")


def _is_number(word: str) -> bool:
    try:
        float(word)
    except ValueError:
        return False
    return True
