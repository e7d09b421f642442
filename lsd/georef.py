"""Where a LAS/LAZ file's coordinates are: its coordinate reference system (read with
pyproj from the file's WKT or GeoTIFF keys) and its horizontal and vertical units.

The detector works in metres; :class:`Georeference` converts the file's units to metres on
the way in (international foot 0.3048 m, US survey foot 1200/3937 m, or any unit pyproj
knows) and back to the file's CRS, and to WGS84 latitude/longitude, on the way out. A file
without a CRS is taken as metres, and says so in one line (:attr:`Georeference.note`).

A LAS/LAZ file in longitude/latitude degrees (EPSG:4326, or compound with a height, as drone
photogrammetry exports) is projected on the way in to a transverse Mercator centred on the
file, on the file's own datum (as a GeoTIFF in degrees is, sitl/terrain/geotiff.py), and
back to degrees on the way out.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np


class GeoreferenceError(ValueError):
    """A CRS the detector cannot work in (geographic degrees, geocentric)."""


MAX_DEGREES_SPAN = 3.0
"""Widest cloud in degrees projected to one transverse Mercator: its scale error stays
below 0.04% at the edge (1 + (x / R)^2 / 2 for x the distance from the centre)."""
MAX_LATITUDE = 85.0


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
        projection: for a file in longitude/latitude degrees, the transverse Mercator
            (pyproj CRS, metres) its x = lon, y = lat are projected to; None for a file in
            a projected CRS or without one (then ``horizontal_unit`` scales x and y;
            with a projection it is 1).
        centre: (lon, lat) degrees of the projection's centre, in the file's CRS.
    """

    crs: Any = None
    horizontal_unit: float = 1.0
    vertical_unit: float = 1.0
    unit_name: str = "metre"
    note: str | None = None
    projection: Any = None
    centre: tuple[float, float] | None = None

    @cached_property
    def label(self) -> str:
        """The CRS as a user names it: ``EPSG:2264`` or its name; "none" without one."""
        if self.crs is None:
            return "none"
        code = self.crs.to_epsg(min_confidence=70)
        return f"EPSG:{code}" if code else self.crs.name

    @cached_property
    def _from_file(self) -> Any:
        from pyproj import Transformer

        return Transformer.from_crs(_horizontal(self.crs), self.projection, always_xy=True)

    @cached_property
    def _to_file(self) -> Any:
        from pyproj import Transformer

        return Transformer.from_crs(self.projection, _horizontal(self.crs), always_xy=True)

    def to_metres(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The file's x, y (arrays) -> metres: scaled, or projected (lon, lat degrees)."""
        if self.projection is None:
            return x * self.horizontal_unit, y * self.horizontal_unit
        return self._from_file.transform(x, y)

    def to_file(self, xyz_m: np.ndarray) -> np.ndarray:
        """(N, 3) metres -> (N, 3) coordinates in the file's CRS and units."""
        out = np.array(xyz_m, dtype=np.float64, copy=True).reshape(-1, 3)
        if self.projection is None:
            out[:, :2] /= self.horizontal_unit
        elif len(out):
            out[:, 0], out[:, 1] = self._to_file.transform(out[:, 0], out[:, 1])
        out[:, 2] /= self.vertical_unit
        return out

    def to_lonlat(self, xy_m: np.ndarray) -> np.ndarray | None:
        """(N, 2) metres -> (N, 2) WGS84 longitude, latitude (degrees); None without a
        CRS."""
        if self.crs is None:
            return None
        from pyproj import CRS, Transformer

        if self.projection is None:
            xy = np.asarray(xy_m, dtype=np.float64).reshape(-1, 2) / self.horizontal_unit
            source = _horizontal(self.crs)
        else:
            xy = np.asarray(xy_m, dtype=np.float64).reshape(-1, 2)
            source = self.projection
        to_wgs84 = Transformer.from_crs(source, CRS.from_epsg(4326), always_xy=True)
        lon, lat = to_wgs84.transform(xy[:, 0], xy[:, 1])
        return np.column_stack((lon, lat))


def georeference(header: Any, path: Path | str = "") -> Georeference:
    """The :class:`Georeference` of a laspy header: a geographic CRS (degrees) is projected
    to a transverse Mercator centred on the header's extent. Raises GeoreferenceError (a
    ValueError naming ``path``) for a geocentric CRS or a cloud in degrees too wide or too
    near a pole for one transverse Mercator."""
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
    if _horizontal(crs).is_geographic:
        return _projected_locally(crs, np.asarray(header.mins), np.asarray(header.maxs), path)
    return from_crs(crs, path)


def _projected_locally(crs: Any, mins: np.ndarray, maxs: np.ndarray,
                       path: Path | str) -> Georeference:
    """The :class:`Georeference` of a file in lon/lat degrees: x, y projected to a
    transverse Mercator centred on the extent, on the file's own datum."""
    from pyproj.crs import ProjectedCRS
    from pyproj.crs.coordinate_operation import TransverseMercatorConversion

    horizontal = _horizontal(crs)
    what = f"{path}: geographic coordinates (degrees, {horizontal.name})"
    if not (np.isfinite(mins[:2]).all() and np.isfinite(maxs[:2]).all()):
        raise GeoreferenceError(f"{what} with a non-finite extent in the header")
    span = float(np.max(maxs[:2] - mins[:2]))
    if span > MAX_DEGREES_SPAN:
        raise GeoreferenceError(f"{what} span {span:.3g} deg, more than the "
                                f"{MAX_DEGREES_SPAN:g} deg one transverse Mercator takes; "
                                "reproject the cloud to a projected CRS first")
    if max(abs(mins[1]), abs(maxs[1])) > MAX_LATITUDE:
        raise GeoreferenceError(f"{what} reach latitude beyond {MAX_LATITUDE:g} deg; "
                                "reproject the cloud to a polar projected CRS first")
    lon, lat = (float(v) for v in (mins[:2] + maxs[:2]) / 2)
    projection = ProjectedCRS(TransverseMercatorConversion(lat, lon),
                              geodetic_crs=horizontal.geodetic_crs.to_2d())
    vertical = _vertical(crs)
    note = None
    if vertical is not None:
        v_unit = float(vertical.axis_info[0].unit_conversion_factor)
    elif len(horizontal.axis_info) > 2:  # a 3D geographic CRS: ellipsoidal height
        v_unit = float(horizontal.axis_info[2].unit_conversion_factor)
    else:
        # No unit for z in a CRS in degrees: metres, as drone photogrammetry writes it.
        v_unit = 1.0
        note = f"{path}: no vertical CRS; z taken as metres"
    return Georeference(crs, 1.0, v_unit, horizontal.axis_info[0].unit_name, note,
                        projection, (lon, lat))


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
