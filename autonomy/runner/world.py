"""Building what a flight needs from its mission: seeds, terrain, simulator, site source."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any
from urllib.parse import urlsplit

import numpy as np

from autonomy.config import Mission
from autonomy.errors import UserError
from autonomy.perception.base import SiteSource
from autonomy.perception.scripted import ScriptedSiteSource


@dataclass(frozen=True)
class FlightSeeds:
    """Independent seeds of a flight's random parts, all derived from the mission seed."""

    terrain: int
    sitl: int
    perception: int
    tree: int
    descent_flow: int  # the descent watch's camera (grain and read noise)

    @classmethod
    def derive(cls, seed: int) -> FlightSeeds:
        """Spawn child seeds with numpy's SeedSequence, so the parts never share a stream.
        A child depends only on its index, so a part added last leaves the others' seeds as
        they were."""
        children = np.random.SeedSequence(seed).spawn(5)
        return cls(*(int(c.generate_state(1, dtype=np.uint32)[0]) for c in children))


def build_terrain(mission: Mission, seed: int) -> Any:
    """The simulated world's :class:`sitl.terrain.Terrain`."""
    from sitl.terrain import make_terrain

    try:
        return make_terrain(mission.world, seed=seed)
    except (OSError, ValueError) as exc:  # e.g. a missing or unreadable elevation file
        raise UserError(f"world: {exc}") from None


def build_source(mission: Mission, terrain: Any, rng: np.random.Generator) -> SiteSource:
    """The perception source the mission selects, seeing ``terrain``."""
    perception = mission.perception
    if perception.detector == "scripted":
        return ScriptedSiteSource(
            mission.sites, perception.scripted, rng=rng,
            height=None if terrain is None else terrain.height,
        )
    if perception.detector == "elevation_map":
        from autonomy.perception.elevation import ElevationMapSource

        return ElevationMapSource.from_settings(
            terrain, rng=rng, camera=perception.camera, rangefinder=perception.rangefinder,
            elevation_map=perception.elevation_map, detector=perception.detection,
        )
    if perception.detector == "depth_costmap":
        from autonomy.perception.costmap import DepthCostmapSource

        return DepthCostmapSource.from_settings(
            terrain, rng=rng, camera=perception.camera, rangefinder=perception.rangefinder,
            detector=perception.depth_costmap,
        )
    if perception.detector == "lidar_pca":
        from autonomy.perception.lidar import LidarPcaSource

        return LidarPcaSource.from_settings(
            terrain, rng=rng, lidar=perception.lidar, detector=perception.lidar_pca
        )
    raise UserError(f"perception.detector: unknown detector {perception.detector!r}")


def build_descent_flow(mission: Mission, terrain: Any, seed: int) -> Any:
    """The descent watch's camera (:class:`autonomy.perception.descent_flow.DescentFlow`)
    when ``landing.descent_watch`` is enabled, else None (nothing built or drawn)."""
    if not mission.landing.descent_watch.enabled or terrain is None:
        return None
    from autonomy.perception.descent_flow import DescentFlow

    return DescentFlow(terrain, mission.perception.descent_flow, seed)


def build_sitl(mission: Mission, terrain: Any, seed: int) -> Any:
    """The embedded simulator for a sim:// flight; ``sim://px4`` or ``sim://ardupilot``
    chooses the personality, otherwise ``vehicle.autopilot`` does. With a signing key in the
    mission the simulator signs with it too, as a vehicle set up with that key would."""
    from sitl import Sitl

    url = urlsplit(mission.vehicle.connection)
    autopilot = url.netloc or url.path.strip("/") or mission.vehicle.autopilot
    if autopilot not in ("ardupilot", "px4"):
        raise UserError(f"{mission.vehicle.connection}: the simulator flies 'ardupilot' or "
                        f"'px4', not {autopilot!r}")
    return Sitl(mission.sitl, terrain=terrain, autopilot=autopilot, seed=seed,
                signing_key=mission.vehicle.signing_key_bytes())


def judge_touchdown(terrain: Any, x: float, y: float, t: float | None = None) -> bool | None:
    """Ground-truth safety of a touchdown point (at clock time ``t``: a moving obstacle
    within the clearance then makes it unsafe), or None when it cannot be judged."""
    if terrain is None:
        return None
    try:
        from sitl.terrain.contact import clear_of_moving
        from sitl.terrain.safety import SafetySettings, is_safe
    except ImportError:  # the safety model is not there: nothing to judge with
        return None
    safe = bool(is_safe(terrain, x, y, SafetySettings()))
    if safe and t is not None and getattr(terrain, "moving", None) is not None:
        safe = clear_of_moving(terrain, x, y, t, SafetySettings())
    return safe


def build_collision_watch(terrain: Any, log: Any) -> Any:
    """The lockstep flight's collision counter against ``terrain``'s ground truth
    (:class:`autonomy.runner.collisions.CollisionWatch`), or None without a world."""
    if terrain is None or not hasattr(terrain, "grid"):
        return None
    from autonomy.runner.collisions import CollisionWatch
    from sitl.terrain.contact import ContactJudge

    return CollisionWatch(ContactJudge(terrain), log)
