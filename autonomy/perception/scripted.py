"""The scripted site source: landing sites listed in the mission file, "seen" from the air.

A test and tutorial source. Each listed site is revealed when it lies inside the downward
sensor's footprint (a cone of ``fov`` degrees under the vehicle, up to ``max_range`` metres
of slant range); every update re-detects every site in view, with horizontal and vertical
position noise whose standard deviation grows with the height above the site
(``noise_base + noise_per_metre * height``). The observation altitude is the vehicle's height
above the site, so flying low over a site verifies it - unless the site is marked
``verifies: false``, in which case it is never reported below ``low_altitude`` (a site that
looks fine from cruise altitude but fails verification).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from behaviors.ports import VehicleState
from behaviors.settings import MAX_ALTITUDE, MAX_RANGE
from lsm.records import SiteObservation

HeightFunction = Callable[[np.ndarray, np.ndarray], np.ndarray]


class ScriptedSite(BaseModel):
    """One landing site of the scripted source (ENU metres)."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    x: float = Field(
        ge=-MAX_RANGE, le=MAX_RANGE, description="ENU east, m, within 50 km of home (a "
        "multicopter's range)"
    )
    y: float = Field(
        ge=-MAX_RANGE, le=MAX_RANGE, description="ENU north, m, within 50 km of home"
    )
    z: float | None = Field(
        None, ge=-MAX_ALTITUDE, le=MAX_ALTITUDE, description="ground height, m, within 10 km "
        "of home's; default: the terrain's height"
    )
    roughness: float = Field(0.1, ge=0, le=1, description="0 (smooth) .. 1")
    uncertainty: float = Field(0.1, ge=0, le=1, description="0 (certain) .. 1")
    size: float = Field(
        3.0, ge=0, le=MAX_RANGE, description="radius of the landable circle, m, up to 50 km"
    )
    obstacle_altitude: float | None = Field(
        None, ge=-MAX_ALTITUDE, le=MAX_ALTITUDE, description="ENU z of the highest terrain to "
        "clear, m, within 10 km of home's; default: the site's z"
    )
    verifies: bool = Field(True, description="false: never re-detected at low altitude")


class ScriptedSettings(BaseModel):
    """Sensor model of the scripted source."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    fov: float = Field(90.0, gt=0, lt=180, description="full field of view, degrees")
    max_range: float = Field(
        150.0, gt=0, le=2 * MAX_RANGE, description="largest slant range that sees a site, m, "
        "up to 100 km"
    )
    noise_base: float = Field(
        0.02, ge=0, le=1000, description="position noise 1-sigma at 0 m, m, up to 1 km"
    )
    noise_per_metre: float = Field(
        0.01, ge=0, le=10, description="extra position noise 1-sigma per metre of height, "
        "m/m, up to 10"
    )
    low_altitude: float = Field(
        10.0, gt=0, le=MAX_ALTITUDE, description="below this height a `verifies: false` site "
        "is not seen, m, up to 10 km"
    )


class ScriptedSiteSource:
    """A :class:`~autonomy.perception.base.SiteSource` over a fixed list of sites.

    Args:
        sites: the sites, in mission-file order (their index names them in events).
        settings: the sensor model.
        rng: the seeded generator drawing the position noise.
        height: vectorised terrain height ``h(x, y)`` in ENU metres, used for sites without
            ``z``; None means flat ground at z = 0.
    """

    def __init__(
        self,
        sites: Sequence[ScriptedSite],
        settings: ScriptedSettings | None = None,
        *,
        rng: np.random.Generator,
        height: HeightFunction | None = None,
    ) -> None:
        self.settings = settings or ScriptedSettings()
        self._rng = rng
        n = len(sites)
        xy = np.array([(s.x, s.y) for s in sites], dtype=np.float64).reshape(n, 2)
        if height is None:
            ground = np.zeros(n)
        else:
            ground = np.asarray(height(xy[:, 0], xy[:, 1]), dtype=np.float64).reshape(n)
        z = np.array([ground[i] if s.z is None else s.z for i, s in enumerate(sites)])
        self._xy = xy
        self._x, self._y = xy[:, 0].copy(), xy[:, 1].copy()  # contiguous columns
        self._z = z.reshape(n)
        self._obstacle = np.array(
            [z[i] if s.obstacle_altitude is None else s.obstacle_altitude
             for i, s in enumerate(sites)]
        ).reshape(n)
        self._roughness = np.array([s.roughness for s in sites]).reshape(n)
        self._uncertainty = np.array([s.uncertainty for s in sites]).reshape(n)
        self._size = np.array([s.size for s in sites]).reshape(n)
        self._verifies = np.array([s.verifies for s in sites], dtype=bool).reshape(n)
        self._table = np.column_stack((self._x, self._y, self._z, self._roughness,
                                       self._uncertainty, self._size, self._obstacle))
        self._revealed = np.zeros(n, dtype=bool)
        self._events: list[dict[str, Any]] = []
        self._dropped: dict[str, int] = {}
        self.observations = 0

    @property
    def sites_xyz(self) -> np.ndarray:
        """(N, 3) ENU metres of the true site centres."""
        return np.column_stack((self._xy, self._z))

    def counters(self) -> dict[str, int]:
        """Observations emitted and updates dropped (``dropped_<reason>``)."""
        out = {"observations": self.observations}
        out.update({f"dropped_{k}": v for k, v in sorted(self._dropped.items())})
        return out

    def _drop(self, reason: str) -> list[SiteObservation]:
        if reason not in self._dropped:
            self._events.append({"event": "perception_dropped", "reason": reason})
        self._dropped[reason] = self._dropped.get(reason, 0) + 1
        return []

    def update(self, state: VehicleState, now: float) -> list[SiteObservation]:
        """Observations of every site in view from ``state.position`` at clock time ``now``."""
        if state.position is None:
            return self._drop("no_position")
        pos = np.asarray(state.position, dtype=np.float64)
        if pos.shape != (3,) or not all(math.isfinite(v) for v in pos.tolist()):
            return self._drop("bad_position")
        if len(self._z) == 0:
            return []
        s = self.settings
        height = pos[2] - self._z
        horizontal = np.hypot(self._x - pos[0], self._y - pos[1])
        slant = np.hypot(horizontal, height)
        in_view = (
            (height > 0)
            & (horizontal <= height * math.tan(math.radians(s.fov) / 2))
            & (slant <= s.max_range)
            & (self._verifies | (height >= s.low_altitude))
        )
        idx = in_view.nonzero()[0]  # np.flatnonzero of a 1-D array, in one call
        if idx.size == 0:
            return []
        above = height[idx]
        sigma = s.noise_base + s.noise_per_metre * above
        noise = self._rng.standard_normal((idx.size, 3)) * sigma[:, None]
        revealed = self._revealed[idx]
        if not all(revealed.tolist()):
            for i in idx[~revealed]:
                self._events.append(
                    {"event": "site_revealed", "site": int(i), "x": float(self._xy[i, 0]),
                     "y": float(self._xy[i, 1]), "height": float(height[i])}
                )
            self._revealed[idx] = True
        # Python floats from here: the same double arithmetic as numpy's, cheaper. One row
        # per site in view: x, y, z, roughness, uncertainty, size, obstacle altitude.
        rows = self._table[idx].tolist()
        shifts = noise.tolist()
        now = float(now)
        observations = []
        for (x, y, z, rough, unc, size, obstacle), (dx, dy, dz), h in zip(
                rows, shifts, above.tolist(), strict=True):
            z += dz
            observations.append(SiteObservation(
                x=x + dx, y=y + dy, z=z, roughness=rough, uncertainty=unc, size=size,
                obstacle_altitude=max(obstacle, z), observation_altitude=h, timestamp=now,
                source="scripted",
            ))
        self.observations += len(observations)
        return observations

    def drain_events(self) -> list[dict[str, Any]]:
        events, self._events = self._events, []
        return events
