"""A ground laser emitter and the vehicle's ring of light sensors (Lee et al., Sensors 2019).

An operator on the ground aims a laser at the vehicle; twelve light sensors (CdS cells) on
the vehicle, 30 deg apart around its body, and one looking straight down read the light.
Each sensor's reading is the ambient illuminance of the weather plus the laser's, with
multiplicative noise; a sensor counts as lit when its reading exceeds its threshold over
the ambient level measured at start-up (section 4.1.1). The model:

* Laser illuminance at distance d: E(d) = E_15 * (15 m / d)^p, fitted per condition to the
  paper's table 2 (laser minus ambient at 15 m and 30 m): the sunny sky washes the laser out
  beyond about a hundred metres, at night it carries for kilometres.
* Line of sight: the beam from the emitter (``emitter_height`` above the ground) to the
  vehicle is sampled every ``los_step`` metres against the terrain; blocked -> no laser.
* Which sensors see it: the one whose 30 deg sector holds the light's azimuth (relative to
  the nose), plus every sensor facing the light whose place on the ring lies inside the beam
  spot: the spot's radius grows with range (``beam_divergence``), so neighbours light up
  far away, as the paper observed. Each is attenuated by the cosine of its incidence.
* Elevation: light from more than ``90 - down_half_angle`` deg below the horizon reaches the
  downward sensor instead of the ring (the vehicle is over the emitter).
* Reflections: with probability ``reflection_rate`` per reading a random ring sensor is lit
  by a momentary reflection.

The result of one reading is a bit mask: bit i (0..11) is the ring sensor centred i * 30 deg
clockwise from the nose, bit 12 the downward sensor. The SITL publishes it over MAVLink as
NAMED_VALUE_INT "LASER_RING" (see docs/gps-denied.md), as a companion computer reading the
sensor board would.
"""

from __future__ import annotations

import math
from typing import Annotated, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

RING_SENSORS = 12
SECTOR = 2.0 * math.pi / RING_SENSORS
DOWN_BIT = 1 << RING_SENSORS
MESSAGE_NAME = "LASER_RING"  # NAMED_VALUE_INT.name (at most 10 characters)

Condition = Literal["sunny", "cloudy", "night", "indoor"]
# A coordinate of the emitter: within 50 km of home, as far as a multicopter flies.
Coordinate = Annotated[
    float, Field(ge=-50_000, le=50_000, description="m from home, -50 km .. 50 km")
]

# Table 2 of the paper, lux: (ambient 15 m, laser projected 15 m, ambient 30 m, projected 30 m).
TABLE_2: dict[str, tuple[float, float, float, float]] = {
    "sunny": (10820.45, 30306.2, 11781.6, 20264.17),
    "cloudy": (7031.69, 31509.4, 7250.12, 15792.0),
    "night": (2.31, 32870.2, 2.82, 14827.4),
    "indoor": (202.59, 41238.2, 133.4, 24834.0),
}


def condition_model(condition: str) -> tuple[float, float, float]:
    """(ambient lux, laser lux at 15 m, range exponent p) fitted to table 2."""
    a15, l15, a30, l30 = TABLE_2[condition]
    laser15, laser30 = l15 - a15, l30 - a30
    exponent = math.log(laser15 / laser30) / math.log(2.0)
    return 0.5 * (a15 + a30), laser15, exponent


class LaserSettings(BaseModel):
    """The ground laser and the light sensors reading it."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    emitter: tuple[Coordinate, Coordinate] | None = Field(
        None, description="ENU x, y (m from home) of the laser on the ground; None: nobody "
        "aims one (the sensors still read ambient light and reflections)"
    )
    emitter_height: float = Field(
        1.5, ge=0, le=100, description="m above the ground the laser is held, up to 100 (a roof)"
    )
    condition: Condition = Field(
        "cloudy", description="ambient light: sunny, cloudy, night or indoor (table 2)"
    )
    power: float = Field(
        1.0, gt=0, le=1000, description="laser illuminance relative to the paper's commercial "
        "laser (table 2), 0..1000"
    )
    rate: float = Field(10.0, gt=0, le=100, description="sensor readings per second, Hz")
    threshold_ratio: float = Field(
        1.3, ge=1, le=100, description="a sensor is lit above this multiple of the ambient "
        "light it measured at start-up (plus threshold_margin)"
    )
    threshold_margin: float = Field(
        50.0, ge=0, le=100_000, description="lux added to the threshold, so that a dark night's "
        "few lux of noise light nothing"
    )
    noise: float = Field(
        0.05, ge=0, le=1, description="relative 1-sigma noise of each reading"
    )
    ring_radius: float = Field(0.15, gt=0, le=5, description="m from the vehicle's centre")
    beam_divergence: float = Field(
        2.0, gt=0, le=100, description="full angle of the beam, mrad (a hand-held laser: 1-3)"
    )
    down_half_angle: float = Field(
        15.0, gt=0, lt=90, description="deg: the downward sensor sees light from within this "
        "angle of straight down; the ring sees everything shallower"
    )
    reflection_rate: float = Field(
        0.05, ge=0, le=1, description="chance per reading of a momentary reflection lighting a "
        "random ring sensor"
    )
    los_step: float = Field(
        2.0, gt=0, le=100, description="m between the samples of the beam checked against the "
        "terrain"
    )


class LightSensorRing:
    """Reads the ring of light sensors for a vehicle pose.

    Args:
        settings: the laser and sensors; ``settings.emitter`` must be set.
        height: terrain height function ``height(x, y) -> array`` (vectorised, ENU m).
        rng: the generator for the sensor noise and reflections.
    """

    def __init__(self, settings: LaserSettings, height, rng: np.random.Generator) -> None:
        self.settings = settings
        self.height = height
        self.rng = rng
        ambient, self.laser_15m, self.exponent = condition_model(settings.condition)
        self.ambient = ambient
        # Threshold over the start-up ambient reading (the paper's "initial brightness").
        self.threshold = settings.threshold_ratio * ambient + settings.threshold_margin
        # No emitter: the ring reads ambient light and reflections only (nobody aims a laser).
        self.emitter_position: tuple[float, float, float] | None = None
        if settings.emitter is not None:
            ex, ey = settings.emitter
            ground = float(np.asarray(height(np.array([ex]), np.array([ey]))).ravel()[0])
            self.emitter_position = (float(ex), float(ey), ground + settings.emitter_height)
        self.centres = np.arange(RING_SENSORS) * SECTOR  # clockwise from the nose

    def line_of_sight(self, position: tuple[float, float, float]) -> bool:
        """True when the beam from the emitter to ``position`` clears the terrain."""
        ex, ey, ez = self.emitter_position
        x, y, z = position
        length = math.dist((ex, ey, ez), (x, y, z))
        n = int(min(max(math.ceil(length / self.settings.los_step), 2), 5000))
        t = np.linspace(0.0, 1.0, n + 1)[1:-1]  # the ends are the emitter and the vehicle
        if t.size == 0:
            return True
        ground = np.asarray(self.height(ex + t * (x - ex), ey + t * (y - ey)), dtype=np.float64)
        beam = ez + t * (z - ez)
        return bool(np.all(~(ground > beam)))  # NaN ground (no data) does not block

    def illuminance(self, distance: float) -> float:
        """Laser illuminance (lux) on a sensor facing it at ``distance`` m."""
        scale = self.settings.power * self.laser_15m
        return scale * (15.0 / max(distance, 0.5)) ** self.exponent

    def read(self, position: tuple[float, float, float], heading: float) -> int:
        """One reading for the vehicle at ENU ``position`` with compass ``heading`` (rad
        clockwise from north): the bit mask of lit sensors."""
        s = self.settings
        rng = self.rng
        ring_light = np.zeros(RING_SENSORS)
        down_light = 0.0
        if self.emitter_position is not None and self.line_of_sight(position):
            ex, ey, ez = self.emitter_position
            x, y, z = position
            dx, dy, dz = ex - x, ey - y, ez - z
            horizontal = math.hypot(dx, dy)
            distance = math.hypot(horizontal, dz)
            laser = self.illuminance(distance)
            below = math.degrees(math.atan2(-dz, horizontal))  # deg below the horizon
            if below >= 90.0 - s.down_half_angle:
                down_light = laser * max(-dz, 0.0) / max(distance, 1e-9)
            else:
                # Azimuth of the light relative to the nose, clockwise (compass convention).
                azimuth = math.atan2(dx, dy) - heading
                offset = (azimuth - self.centres + math.pi) % (2.0 * math.pi) - math.pi
                spot = distance * math.tan(0.5e-3 * s.beam_divergence)
                facing = np.abs(offset) < 0.5 * math.pi
                in_sector = np.abs(offset) <= 0.5 * SECTOR
                in_spot = facing & (s.ring_radius * np.abs(np.sin(offset)) <= spot)
                lit = in_sector | in_spot
                incidence = np.cos(np.clip(offset, -0.5 * math.pi, 0.5 * math.pi))
                cos_elevation = horizontal / max(distance, 1e-9)
                ring_light = np.where(lit, laser * np.maximum(incidence, 0.2) * cos_elevation, 0.0)
        # Every sensor reads ambient light with noise, whether the laser is there or not.
        noise = 1.0 + s.noise * rng.standard_normal(RING_SENSORS + 1)
        readings = (self.ambient + np.r_[ring_light, down_light]) * noise
        mask = int(np.sum((readings > self.threshold) << np.arange(RING_SENSORS + 1)))
        if rng.random() < s.reflection_rate:
            mask |= 1 << int(rng.integers(RING_SENSORS))
        return mask
