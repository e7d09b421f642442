"""Readers for recorded sensor data: point clouds (.npy, PLY ascii/binary, LAS/LAZ) and depth
images (.npy metres, 16-bit PNG in depth units, float or 16-bit TIFF).

Every reader raises :class:`DataFileError` with a one-line reason naming the file when the
file is not what its extension says; the command line turns it into a user error.
"""

from __future__ import annotations

import contextlib
import warnings
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from lsd.georef import Georeference, GeoreferenceError, georeference

# ASPRS LAS 1.4 standard classification codes (the ones a landing decision cares about).
LAS_CLASSES: dict[int, str] = {
    0: "never classified",
    1: "unclassified",
    2: "ground",
    3: "low vegetation",
    4: "medium vegetation",
    5: "high vegetation",
    6: "building",
    7: "noise",
    8: "model key point",
    9: "water",
    10: "rail",
    11: "road surface",
    13: "wire guard",
    14: "wire conductor",
    15: "transmission tower",
    17: "bridge deck",
    18: "high noise",
}

_PLY_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1",
    "short": "i2", "int16": "i2", "ushort": "u2", "uint16": "u2",
    "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}  # fmt: skip
_CLASS_NAMES = ("classification", "class", "scalar_classification", "label")


class DataFileError(ValueError):
    """A data file that cannot be read as what its extension says (message names it)."""


@dataclass
class CloudData:
    """A point cloud read from a file.

    Attributes:
        points: (N, 3) float64 x, y, z in metres (LAS/LAZ: converted from the file's units;
            other formats: taken as metres; rows may hold NaN).
        classification: (N,) int64 ASPRS class codes, or None when the file has none.
        georef: the file's coordinate reference (CRS, units), or None (not a LAS/LAZ file).
        withheld: LAS/LAZ points flagged withheld, whose rows in ``points`` are NaN (the
            LAS specification: such a point is deleted and must not be used).
    """

    points: np.ndarray
    classification: np.ndarray | None = None
    georef: Georeference | None = None
    withheld: int = 0


def class_name(code: int) -> str:
    """ASPRS name of a LAS class code ("class N" when unknown)."""
    return LAS_CLASSES.get(int(code), f"class {int(code)}")


MAX_IMAGE_PIXELS = 50_000_000
"""A depth image holds at most 50 megapixels: depth cameras give a few; 50 MP of float32 is
200 MB, and each costmap is another such layer."""


@contextlib.contextmanager
def _quiet() -> Iterator[None]:
    """No library warnings while a file is read: a bad file is reported as one line."""
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore")
        yield


def _check_file(p: Path) -> None:
    """Refuse a path that is not a readable regular file, saying what it is instead."""
    if p.is_dir():
        raise DataFileError(f"{p}: a directory, not a file")
    if not p.exists():
        raise DataFileError(f"{p}: no such file")
    if not p.is_file():
        raise DataFileError(f"{p}: not a regular file")


def read_point_cloud(path: str | Path) -> CloudData:
    """Read a cloud by extension: ``.npy`` (N, >=3), ``.ply``, ``.las``/``.laz``."""
    p = Path(path)
    _check_file(p)
    ext = p.suffix.lower()
    with _quiet():
        if ext == ".npy":
            return _read_npy_cloud(p)
        if ext == ".ply":
            return read_ply(p)
        if ext in (".las", ".laz"):
            return read_las(p)
    raise DataFileError(f"{p}: unknown point-cloud extension {ext!r} (use .npy, .ply, .las, .laz)")


def load_npy(p: Path) -> np.ndarray:
    """A numeric array from a ``.npy`` file; DataFileError with the reason otherwise."""
    try:
        with _quiet():
            arr = np.load(p, allow_pickle=False)
    except Exception as exc:  # noqa: BLE001 - a damaged header raises several types
        reason = " ".join(str(exc).split())[:200] or type(exc).__name__
        raise DataFileError(f"{p}: not a NumPy .npy array ({reason})") from None
    if not isinstance(arr, np.ndarray) or arr.dtype.kind not in "fiu":
        raise DataFileError(f"{p}: expected a numeric array, got dtype {arr.dtype}")
    return arr


def _read_npy_cloud(p: Path) -> CloudData:
    arr = load_npy(p)
    if arr.ndim != 2 or arr.shape[1] not in (3, 4):
        raise DataFileError(
            f"{p}: expected an (N, 3) array of x, y, z (or (N, 4) with an ASPRS class "
            f"column), got shape {arr.shape}"
        )
    codes = None
    if arr.shape[1] == 4:
        codes = arr[:, 3]
        if not (np.isfinite(codes).all() and (codes == np.round(codes)).all()
                and (codes >= 0).all() and (codes <= 255).all()):
            raise DataFileError(f"{p}: column 4 must hold ASPRS class codes 0..255")
        codes = codes.astype(np.int64)
    return CloudData(np.asarray(arr[:, :3], dtype=np.float64), codes)


def read_ply(path: str | Path) -> CloudData:
    """Read the ``vertex`` element of a PLY file (ascii, binary little or big endian).

    x, y, z are required; a ``classification`` (or ``class``/``label``) property is returned
    when present. Elements before ``vertex`` may be skipped only if they have no list
    properties.
    """
    p = Path(path)
    with open(p, "rb") as f:
        if f.readline().strip() != b"ply":
            raise DataFileError(f"{p}: not a PLY file (no 'ply' magic line)")
        fmt = None
        elements: list[tuple[str, int, list[tuple[str, str | None]]]] = []
        while True:
            raw = f.readline()
            if not raw:
                raise DataFileError(f"{p}: PLY header has no end_header")
            words = raw.decode("ascii", errors="replace").split()
            if not words or words[0] in ("comment", "obj_info"):
                continue
            if words[0] == "end_header":
                break
            if words[0] == "format" and len(words) >= 2:
                fmt = words[1]
            elif words[0] == "element" and len(words) == 3:
                elements.append((words[1], _int(words[2], p), []))
            elif words[0] == "property" and elements:
                if len(words) < 3:
                    raise DataFileError(f"{p}: bad PLY property line {' '.join(words)!r}")
                if words[1] == "list":
                    elements[-1][2].append((words[-1], None))
                elif len(words) == 3 and words[1] in _PLY_TYPES:
                    elements[-1][2].append((words[2], _PLY_TYPES[words[1]]))
                else:
                    raise DataFileError(f"{p}: bad PLY property line {' '.join(words)!r}")
        if fmt not in ("ascii", "binary_little_endian", "binary_big_endian"):
            raise DataFileError(f"{p}: unsupported PLY format {fmt!r}")
        names = [e[0] for e in elements]
        if "vertex" not in names:
            raise DataFileError(f"{p}: PLY file has no vertex element")
        vi = names.index("vertex")
        for name, _count, props in elements[: vi + 1]:
            if any(t is None for _, t in props):
                raise DataFileError(f"{p}: PLY element {name!r} has list properties")
        _, count, props = elements[vi]
        prop_names = [n for n, _ in props]
        if not {"x", "y", "z"} <= set(prop_names):
            raise DataFileError(f"{p}: PLY vertex element lacks x, y, z")
        if count == 0:
            raise DataFileError(f"{p}: the PLY file holds no points (element vertex 0)")
        if fmt == "ascii":
            skip = sum(c for _, c, _ in elements[:vi])
            for _ in range(skip):
                if not f.readline():
                    raise DataFileError(f"{p}: PLY ascii data ends before the vertex element")
            left = p.stat().st_size - f.tell()
            if count * len(props) * 2 > left + 1:  # each value is a digit and a separator
                raise DataFileError(
                    f"{p}: PLY ascii data too short for the header's {count} vertices "
                    f"({left} bytes)"
                )
            try:
                table = np.loadtxt(f, max_rows=count, ndmin=2, dtype=np.float64)
            except ValueError as exc:
                raise DataFileError(f"{p}: bad PLY ascii data ({exc})") from None
            if table.shape != (count, len(props)):
                raise DataFileError(
                    f"{p}: PLY ascii vertex data has shape {table.shape}, header says "
                    f"({count}, {len(props)})"
                )
            col = {n: table[:, i] for i, n in enumerate(prop_names)}
        else:
            order = "<" if fmt == "binary_little_endian" else ">"
            skip = sum(c * np.dtype([(n, order + t) for n, t in pr]).itemsize
                       for _, c, pr in elements[:vi])
            dtype = np.dtype([(n, order + t) for n, t in props])
            left = p.stat().st_size - f.tell() - skip
            if left < dtype.itemsize * count:
                raise DataFileError(
                    f"{p}: PLY binary data truncated ({max(left, 0)} of "
                    f"{dtype.itemsize * count} bytes)"
                )
            f.seek(skip, 1)
            buf = f.read(dtype.itemsize * count)
            if len(buf) < dtype.itemsize * count:
                raise DataFileError(
                    f"{p}: PLY binary data truncated ({len(buf)} of "
                    f"{dtype.itemsize * count} bytes)"
                )
            table = np.frombuffer(buf, dtype=dtype, count=count)
            col = {n: table[n] for n in prop_names}
    points = np.stack([col[k].astype(np.float64) for k in ("x", "y", "z")], axis=1)
    cls = next((col[n] for n in prop_names if n.lower() in _CLASS_NAMES), None)
    return CloudData(points, None if cls is None else np.asarray(cls).astype(np.int64))


def _int(word: str, p: Path) -> int:
    try:
        value = int(word)
    except ValueError:
        raise DataFileError(f"{p}: bad PLY element count {word!r}") from None
    if value < 0:
        raise DataFileError(f"{p}: negative PLY element count {value}")
    return value


def read_las(path: str | Path) -> CloudData:
    """Read a LAS/LAZ file with laspy (optional extra ``las``, which brings the LAZ backend
    lazrs and pyproj): x, y, z in metres and the classification codes, with the file's
    :class:`Georeference`."""
    p = Path(path)
    with open_las(p) as (reader, georef):
        try:
            las = reader.read()
        except Exception as exc:  # noqa: BLE001 - laspy/lazrs raise several types
            raise _not_readable(p, exc) from None
        points, codes = _las_arrays(las.points, georef)
    if len(points) != reader.header.point_count:
        raise DataFileError(f"{p}: truncated LAS/LAZ file ({len(points)} of "
                            f"{reader.header.point_count} points)")
    return CloudData(points, codes, georef, int(np.isnan(points[:, 0]).sum()))


def iter_las_chunks(
    path: str | Path, chunk_points: int = 1_000_000
) -> Iterator[tuple[np.ndarray, np.ndarray | None]]:
    """Stream a LAS/LAZ file in chunks of ``chunk_points`` (laspy's chunk reader): yields
    ``(points (n, 3) metres, classes (n,) or None)``; memory is bounded by the chunk, not the
    file. Use :func:`open_las` first for the header and georeference. Raises DataFileError
    on a file that ends before its header's point count."""
    p = Path(path)
    with open_las(p) as (reader, georef):
        seen = 0
        try:
            for chunk in reader.chunk_iterator(chunk_points):
                points, codes = _las_arrays(chunk, georef)
                seen += len(points)
                yield points, codes
        except DataFileError:
            raise
        except Exception as exc:  # noqa: BLE001 - laspy/lazrs raise several types
            raise _not_readable(p, exc) from None
        if seen != reader.header.point_count:
            raise DataFileError(f"{p}: truncated LAS/LAZ file ({seen} of "
                                f"{reader.header.point_count} points)")


@contextlib.contextmanager
def open_las(path: str | Path):
    """``with open_las(path) as (reader, georef)``: a laspy reader whose header was checked
    (scales, point count against the file size) and the file's :class:`Georeference`."""
    p = Path(path)
    _check_file(p)
    try:
        import laspy  # optional: pip install 'landing-autonomy[las]'
    except ImportError:
        raise DataFileError(
            f"{p}: reading LAS/LAZ needs laspy: pip install 'landing-autonomy[las]'"
        ) from None
    with _quiet():
        try:
            reader = laspy.open(p)
        except Exception as exc:  # noqa: BLE001 - laspy raises several types for a bad file
            raise _not_readable(p, exc) from None
        with reader:
            header = reader.header
            scales, offsets = np.asarray(header.scales), np.asarray(header.offsets)
            if not (np.isfinite(scales).all() and np.isfinite(offsets).all()) or (
                scales == 0
            ).any():
                raise DataFileError(f"{p}: LAS header has a zero or non-finite scale or offset")
            size = p.stat().st_size
            ratio = 50 if header.are_points_compressed else 1  # LAZ compresses ~5-10 to 1
            if header.point_count * header.point_format.size > ratio * size:
                # A count beyond what the file can hold is a bad header: refused before
                # laspy allocates arrays for it.
                raise DataFileError(f"{p}: LAS header claims {header.point_count} points, "
                                    f"more than a {size}-byte file holds")
            if header.point_count == 0:
                raise DataFileError(f"{p}: the LAS/LAZ file holds no points")
            try:
                georef = georeference(header, p)
            except GeoreferenceError as exc:
                raise DataFileError(str(exc)) from None
            yield reader, georef


def _not_readable(p: Path, exc: Exception) -> DataFileError:
    reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
    if "LazBackend" in reason:
        reason = "LAZ needs the lazrs backend: pip install 'landing-autonomy[las]'"
    return DataFileError(f"{p}: not a readable LAS/LAZ file ({reason[:200]})")


def _las_arrays(points, georef: Georeference) -> tuple[np.ndarray, np.ndarray | None]:
    """(n, 3) metres and (n,) class codes of a laspy point record; NaN rows for the points
    flagged withheld (deleted, by the LAS specification; the flag is a bit of the
    classification byte up to point format 5, of the classification flags from 6 on)."""
    xyz = np.empty((len(points), 3))
    xyz[:, 0] = points.x
    xyz[:, 1] = points.y
    xyz[:, 2] = points.z
    if georef.projection is None:
        xyz[:, :2] *= georef.horizontal_unit
    else:  # lon/lat degrees: projected to metres (pyproj, over the arrays)
        xyz[:, 0], xyz[:, 1] = georef.to_metres(xyz[:, 0], xyz[:, 1])
    xyz[:, 2] *= georef.vertical_unit
    withheld = np.asarray(points.withheld, dtype=bool)
    if withheld.any():
        xyz[withheld] = np.nan
    try:
        codes = np.asarray(points.classification).astype(np.int64)
    except Exception:  # noqa: BLE001 - a point format without classification
        codes = None
    return xyz, codes


DEPTH_UNIT = 0.001
"""Metres per unit of an integer depth image unless told otherwise: millimetres, as
RealSense, Azure Kinect and OAK cameras write 16-bit depth (TUM RGB-D and Kinect v1
recordings use 1/5000 m)."""


def read_depth_image(path: str | Path, unit: float = DEPTH_UNIT) -> np.ndarray:
    """Read a depth image: ``.npy`` (H, W) metres; a single-channel 16-bit ``.png``; or a
    single-channel ``.tif``/``.tiff``, 32-bit float in metres or 16-bit (as Pillow reads
    them: 64-bit float TIFFs are not).

    Args:
        path: the image file.
        unit: metres per unit of an integer (16-bit) image; float images are metres.

    Returns (H, W) float32 metres; 0, negative or NaN = no depth.
    """
    p = Path(path)
    _check_file(p)
    ext = p.suffix.lower()
    if ext == ".npy":
        with _quiet():
            depth = load_npy(p)
        if depth.ndim == 3 and depth.shape[2] == 1:
            depth = depth[:, :, 0]
        if depth.ndim != 2:
            raise DataFileError(f"{p}: expected an (H, W) depth array, got shape {depth.shape}")
        _check_pixels(p, depth.shape[1], depth.shape[0])
        with _quiet():  # depths beyond float32 become inf: no depth
            return depth.astype(np.float32)
    if ext == ".png":
        img = _read_image(p, "PNG")
        if img.dtype != np.uint16 or img.ndim != 2:
            raise DataFileError(
                f"{p}: expected a 16-bit single-channel PNG (depth units of {unit:g} m), got "
                f"{img.dtype} with shape {img.shape}"
            )
        return (img * unit).astype(np.float32)
    if ext in (".tif", ".tiff"):
        img = _read_image(p, "TIFF")
        img = img.astype(img.dtype.newbyteorder("="), copy=False)  # big-endian TIFFs too
        if img.ndim != 2 or img.dtype not in (np.float32, np.float64, np.uint16):
            raise DataFileError(
                f"{p}: expected a single-channel TIFF of float metres or 16-bit depth units, "
                f"got {img.dtype} with shape {img.shape}"
            )
        if img.dtype == np.uint16:
            return (img * unit).astype(np.float32)
        with _quiet():
            return img.astype(np.float32)
    raise DataFileError(
        f"{p}: unknown depth-image extension {ext!r} (use .npy, .png, .tif or .tiff)"
    )


def _check_pixels(p: Path, width: int, height: int) -> None:
    if width * height > MAX_IMAGE_PIXELS:
        raise DataFileError(f"{p}: a {width} x {height} image, more than "
                            f"{MAX_IMAGE_PIXELS:,} pixels")


def _read_image(p: Path, kind: str) -> np.ndarray:
    """The pixels of a PNG or TIFF image, decoded by Pillow (libpng, under OpenCV, prints its
    complaints about a damaged file to the terminal; Pillow raises them), its size checked
    before decoding. Pillow comes with matplotlib, a dependency that requires it."""
    from PIL import Image

    try:
        with _quiet(), Image.open(p) as image:
            if image.format != kind:
                raise DataFileError(f"{p}: not a readable {kind} image")
            _check_pixels(p, *image.size)
            return np.array(image)
    except DataFileError:
        raise
    except Image.DecompressionBombError:  # Pillow's own limit, far above ours, on opening
        raise DataFileError(f"{p}: an image of more than {MAX_IMAGE_PIXELS:,} pixels") from None
    except (OSError, SyntaxError, ValueError, EOFError, MemoryError):
        raise DataFileError(f"{p}: not a readable {kind} image") from None


def write_las(path: str | Path, points: np.ndarray, classification: np.ndarray | None = None,
              crs=None, scale: float = 0.001) -> None:
    """Write a cloud (coordinates in the CRS's units) as LAS 1.4 point format 6, or LAZ by
    extension, with its classification and CRS (a pyproj CRS or anything
    ``pyproj.CRS.from_user_input`` takes). Needs the ``las`` extra."""
    import laspy

    pts = np.asarray(points, dtype=np.float64)
    header = laspy.LasHeader(point_format=6, version="1.4")
    header.scales = np.full(3, scale)
    header.offsets = np.floor(pts.min(axis=0)) if len(pts) else np.zeros(3)
    if crs is not None:
        from pyproj import CRS

        header.add_crs(CRS.from_user_input(crs))
    las = laspy.LasData(header)
    las.x, las.y, las.z = pts[:, 0], pts[:, 1], pts[:, 2]
    if classification is not None:
        las.classification = np.asarray(classification, dtype=np.uint8)
    las.write(str(path))


def write_ply(path: str | Path, points: np.ndarray, binary: bool = True) -> None:
    """Write an (N, 3) cloud as a PLY file (float64 x, y, z), ascii or binary little endian."""
    pts = np.asarray(points, dtype=np.float64)
    fmt = "binary_little_endian" if binary else "ascii"
    header = (
        f"ply\nformat {fmt} 1.0\nelement vertex {len(pts)}\n"
        "property double x\nproperty double y\nproperty double z\nend_header\n"
    )
    with open(path, "wb") as f:
        f.write(header.encode("ascii"))
        if binary:
            f.write(pts.astype("<f8").tobytes())
        else:
            np.savetxt(f, pts, fmt="%.17g")  # exact round trip


__all__ = [
    "LAS_CLASSES",
    "CloudData",
    "DataFileError",
    "class_name",
    "read_depth_image",
    "iter_las_chunks",
    "open_las",
    "read_las",
    "read_ply",
    "read_point_cloud",
    "write_las",
    "write_ply",
]
