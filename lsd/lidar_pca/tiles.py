"""Clouds larger than memory: a LAS/LAZ file streamed in chunks (laspy's chunk reader)
through square spatial tiles, each with a margin of the largest site's reach, so memory is
bounded by a chunk and a tile, not by the file, and time is linear in points.

Pass 1 reads the file once and appends each chunk's points to the tiles they belong to
(core and margins), in files under a temporary directory. Pass 2 loads one tile at a time,
searches the cells of its core (grid seeding anchored at 0, voxels on the global lattice)
with the margin around them, and applies the site rules. The sites of all tiles are then
thinned for overlap as one list. A cloud run whole and tiled gives the same sites: every
search point's neighbourhood, clearance ring and rule checks lie within the margin.
"""

from __future__ import annotations

import math
import sys
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from lsd.georef import Georeference
from lsd.io import iter_las_chunks, open_las
from lsd.lidar_pca.coverage import max_reach
from lsd.lidar_pca.detector import SpotTable
from lsd.lidar_pca.settings import LidarPcaSettings
from lsd.lidar_pca.sites import SiteCounts, find_sites, finish_sites
from lsd.pointcloud import MAX_COORDINATE

_RECORD = np.dtype([("xyz", "<f8", (3,)), ("cls", "<i2")])


@dataclass
class TiledResult:
    """Sites of a streamed cloud with their counts, the file's georeference, the tiles
    searched and the number of points read."""

    spots: SpotTable
    counts: SiteCounts
    georef: Georeference
    tiles: int
    points: int


def tile_margin(settings: LidarPcaSettings) -> float:
    """Metres around a tile's core that its search points can reach: the largest radius,
    its step and the clearance ring (or the coverage check's reach beyond the disc, if
    larger), plus two voxels."""
    beyond = max(settings.obstacle_margin, max_reach(settings))
    return settings.r_max + settings.r_step + beyond + 2 * settings.voxel_size


def tile_edge(settings: LidarPcaSettings, tile_size: float) -> float:
    """``tile_size`` rounded up to whole grid-seeding cells (so each cell is in one core)."""
    spacing = settings.grid_spacing or settings.r_max
    return max(1, math.ceil(tile_size / spacing - 1e-9)) * spacing


def detect_tiled(
    path: str | Path,
    settings: LidarPcaSettings,
    rng: np.random.Generator,
    tile_size: float = 200.0,
    chunk_points: int = 1_000_000,
    progress: Callable[[str, float], None] | None = None,
) -> TiledResult:
    """Sites of a LAS/LAZ file, streamed (see the module docstring). Grid seeding only:
    random search points cannot be drawn the same over tiles.

    Args:
        path: the file.
        settings: detector settings (``seeding`` must be ``grid``).
        rng: unused by grid seeding; kept for the detector's signature.
        tile_size: core edge (m), rounded up to whole seeding cells.
        chunk_points: points read at once.
        progress: called with (stage, fraction done).
    """
    if settings.seeding != "grid":
        raise ValueError("seeding: tiles need grid seeding (random search points would "
                         "differ from tile to tile)")
    edge = tile_edge(settings, tile_size)
    margin = tile_margin(settings)
    with open_las(path) as (reader, georef):
        total = int(reader.header.point_count)
    counts = SiteCounts()
    found: list[SpotTable] = []
    read = 0
    classified = False  # the whole file's, so every tile applies the same rules
    with tempfile.TemporaryDirectory(prefix="lander-tiles-") as tmp:
        files: dict[tuple[int, int], Path] = {}
        for points, codes in iter_las_chunks(path, chunk_points):
            read += len(points)
            classified |= codes is not None and bool((codes == 2).any())
            _spill(points, codes, edge, margin, Path(tmp), files)
            if progress:
                progress("reading", read / max(total, 1))
        for k, (key, file) in enumerate(sorted(files.items())):
            tile = np.fromfile(file, dtype=_RECORD)
            file.unlink()
            core = (key[0] * edge, (key[0] + 1) * edge, key[1] * edge, (key[1] + 1) * edge)
            spots, tile_counts = find_sites(
                np.ascontiguousarray(tile["xyz"]), tile["cls"].astype(np.int64), settings,
                rng, core=core, classified=classified,
            )
            tile_counts.points = 0
            counts.merge(tile_counts)
            found.append(spots)
            del tile
            if progress:
                progress("tiles", (k + 1) / len(files))
    counts.points = read
    spots = SpotTable()
    for part in found:
        spots = SpotTable.concat(spots, part)
    spots = finish_sites(spots, settings, counts)
    return TiledResult(spots, counts, georef, len(found), read)


def _spill(points, codes, edge, margin, tmp: Path, files: dict) -> None:
    """Append a chunk's points to the file of every tile whose core or margin holds them."""
    usable = (np.abs(points) <= MAX_COORDINATE).all(axis=1)
    points = points[usable]
    codes = np.zeros(len(points), np.int16) if codes is None else codes[usable].astype(np.int16)
    for tile, rows in _tile_rows(points, edge, margin):
        record = np.empty(len(rows), dtype=_RECORD)
        record["xyz"] = points[rows]
        record["cls"] = codes[rows]
        file = files.setdefault(tile, tmp / f"tile_{tile[0]}_{tile[1]}.bin")
        with open(file, "ab") as f:
            record.tofile(f)


def _tile_rows(points: np.ndarray, edge: float, margin: float):
    """Yield (tile key, rows of ``points`` in its core or margin, in order) per tile."""
    if not len(points):
        return
    tx = np.floor(points[:, 0] / edge).astype(np.int64)
    ty = np.floor(points[:, 1] / edge).astype(np.int64)
    fx = points[:, 0] - tx * edge  # position within the own tile
    fy = points[:, 1] - ty * edge
    keys, rows = [], []
    for dx in (-1, 0, 1):
        near_x = (fx < margin) if dx < 0 else (fx >= edge - margin) if dx > 0 else True
        for dy in (-1, 0, 1):
            near_y = (fy < margin) if dy < 0 else (fy >= edge - margin) if dy > 0 else True
            sel = np.flatnonzero(near_x & near_y) if (dx or dy) else np.arange(len(points))
            keys.append(np.column_stack((tx[sel] + dx, ty[sel] + dy)))
            rows.append(sel)
    key = np.concatenate(keys)
    row = np.concatenate(rows)
    order = np.lexsort((row, key[:, 1], key[:, 0]))  # per tile, in file order
    key, row = key[order], row[order]
    cut = np.flatnonzero(np.any(key[1:] != key[:-1], axis=1)) + 1
    for start, stop in zip(np.r_[0, cut], np.r_[cut, len(row)], strict=True):
        yield (int(key[start, 0]), int(key[start, 1])), row[start:stop]


def detect_in_tiles(
    points: np.ndarray,
    codes: np.ndarray | None,
    settings: LidarPcaSettings,
    rng: np.random.Generator,
    tile_size: float = 200.0,
    progress: Callable[[str, float], None] | None = None,
) -> tuple[SpotTable, SiteCounts]:
    """:func:`detect_tiled` on a cloud already in memory: the search's working memory is
    bounded by a tile (its neighbourhood pairs grow with the search points), with the
    same sites as one search over the whole cloud."""
    edge = tile_edge(settings, tile_size)
    classified = codes is not None and bool((codes == 2).any())
    counts = SiteCounts(points=len(points))
    found = SpotTable()
    tiles = list(_tile_rows(points, edge, tile_margin(settings)))
    for k, (key, rows) in enumerate(tiles):
        core = (key[0] * edge, (key[0] + 1) * edge, key[1] * edge, (key[1] + 1) * edge)
        spots, tile_counts = find_sites(points[rows], None if codes is None else codes[rows],
                                        settings, rng, core=core, classified=classified)
        tile_counts.points = 0
        counts.merge(tile_counts)
        found = SpotTable.concat(found, spots)
        if progress:
            progress("tiles", (k + 1) / len(tiles))
    return finish_sites(found, settings, counts), counts


def stderr_progress(label: str) -> Callable[[str, float], None]:
    """A progress bar on stderr (redrawn in place on a terminal, a line per quarter
    otherwise)."""
    tty = sys.stderr.isatty()
    last = {"stage": None, "step": -1}

    def show(stage: str, fraction: float) -> None:
        step = int(fraction * (40 if tty else 4))
        if stage == last["stage"] and step == last["step"]:
            return
        last.update(stage=stage, step=step)
        if tty:
            bar = "#" * int(fraction * 30)
            end = "\n" if fraction >= 1 else ""
            print(f"\r{label}: {stage:8s} [{bar:30s}] {100 * fraction:5.1f}%", end=end,
                  file=sys.stderr, flush=True)
        else:
            print(f"{label}: {stage} {100 * fraction:.0f}%", file=sys.stderr, flush=True)

    return show


__all__ = [
    "TiledResult",
    "detect_in_tiles",
    "detect_tiled",
    "stderr_progress",
    "tile_edge",
    "tile_margin",
]
