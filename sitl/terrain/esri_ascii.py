"""Reading an ESRI ASCII grid (``.asc``): a header of ``key value`` lines (``ncols``,
``nrows``, ``cellsize``, the lower-left corner or centre, ``NODATA_value``), then ``nrows``
rows of ``ncols`` numbers, north to south.

A malformed file is refused with :class:`GridFileError`, whose text names the file, the line
and what is wrong there. Rows that wrap over several lines are read as GDAL reads them, as one
stream of ``nrows x ncols`` numbers.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import TextIO

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


def read_asc(path: Path) -> tuple[np.ndarray, float, float | None]:
    """(heights north-up (nrows, ncols) float64, cell size, NODATA_value or None)."""
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
    return values.reshape(shape), header["cellsize"], header.get("nodata_value")


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
