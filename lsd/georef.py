"""Where a LAS/LAZ file's coordinates are: its coordinate reference system (read with
pyproj from the file's WKT or GeoTIFF keys) and its horizontal and vertical units.

The detector works in metres; :class:`Georeference` converts the file's units to metres on
the way in (international foot 0.3048 m, US survey foot 1200/3937 m, or any unit pyproj
knows) and back to the file's CRS, and to WGS84 latitude/longitude, on the way out. A file
without a CRS is taken as metres, and says so in one line (:attr:`Georeference.note`).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np


class GeoreferenceError(ValueError):
    """A CRS the detector cannot work in (geographic degrees, geocentric)."""


@dataclass(frozen=True)
class Georeference:
    """A file's coordinate reference.

    Attributes:
        crs: the file's pyproj CRS (None: none in the file, or not understood).
        horizontal_unit: metres per file unit of x and y.
        vertical_unit: metres per file unit of z.
        unit_name: the horizontal unit's name ("metre", "US survey foot", ...).
        note: one line for the user when something was assumed (no CRS, vertical unit),
            else None.
    """

    crs: Any = None
    horizontal_unit: float = 1.0
    vertical_unit: float = 1.0
    unit_name: str = "metre"
    note: str | None = None

    @cached_property
    def label(self) -> str:
        """The CRS as a user names it: ``EPSG:2264`` or its name; "none" without one."""
        if self.crs is None:
            return "none"
        code = self.crs.to_epsg(min_confidence=70)
        return f"EPSG:{code}" if code else self.crs.name

    def to_file(self, xyz_m: np.ndarray) -> np.ndarray:
        """(N, 3) metres -> (N, 3) coordinates in the file's CRS and units."""
        out = np.array(xyz_m, dtype=np.float64, copy=True).reshape(-1, 3)
        out[:, :2] /= self.horizontal_unit
        out[:, 2] /= self.vertical_unit
        return out

    def to_lonlat(self, xy_m: np.ndarray) -> np.ndarray | None:
        """(N, 2) metres -> (N, 2) WGS84 longitude, latitude (degrees); None without a
        CRS."""
        if self.crs is None:
            return None
        from pyproj import CRS, Transformer

        xy = np.asarray(xy_m, dtype=np.float64).reshape(-1, 2) / self.horizontal_unit
        horizontal = _horizontal(self.crs)
        to_wgs84 = Transformer.from_crs(horizontal, CRS.from_epsg(4326), always_xy=True)
        lon, lat = to_wgs84.transform(xy[:, 0], xy[:, 1])
        return np.column_stack((lon, lat))


def georeference(header: Any, path: Path | str = "") -> Georeference:
    """The :class:`Georeference` of a laspy header. Raises GeoreferenceError (a
    ValueError naming ``path``) for a geographic or geocentric CRS."""
    has_vlr = any(
        getattr(v, "user_id", "") == "LASF_Projection"
        for v in list(header.vlrs) + list(getattr(header, "evlrs", None) or [])
    )
    try:
        crs = header.parse_crs()
    except Exception:  # noqa: BLE001 - pyproj missing or a malformed VLR
        crs = None
    if crs is None:
        why = "a CRS record it cannot read" if has_vlr else "no CRS"
        return Georeference(note=f"{path}: {why}; coordinates taken as metres")
    return from_crs(crs, path)


def from_crs(crs: Any, path: Path | str = "") -> Georeference:
    """The :class:`Georeference` of a pyproj CRS (units from its axes)."""
    horizontal = _horizontal(crs)
    if horizontal.is_geographic:
        raise GeoreferenceError(
            f"{path}: geographic coordinates (degrees, {horizontal.name}); reproject the "
            "cloud to a projected CRS in metres or feet first"
        )
    if horizontal.is_geocentric or not horizontal.is_projected:
        raise GeoreferenceError(f"{path}: CRS {horizontal.name!r} is not a projected CRS")
    axis = horizontal.axis_info[0]
    h_unit = float(axis.unit_conversion_factor)
    vertical = _vertical(crs)
    note = None
    if vertical is not None:
        v_unit = float(vertical.axis_info[0].unit_conversion_factor)
    else:
        # LAS files give z in the horizontal unit unless a vertical CRS says otherwise.
        v_unit = h_unit
        if h_unit != 1.0:
            note = f"{path}: no vertical CRS; z taken in the unit of x and y ({axis.unit_name})"
    return Georeference(crs, h_unit, v_unit, axis.unit_name, note)


def _horizontal(crs: Any) -> Any:
    if crs.is_compound:
        return crs.sub_crs_list[0]
    return crs


def _vertical(crs: Any) -> Any:
    if crs.is_compound and len(crs.sub_crs_list) > 1:
        return crs.sub_crs_list[1]
    if crs.is_vertical:
        return crs
    return None


__all__ = ["Georeference", "GeoreferenceError", "from_crs", "georeference"]
