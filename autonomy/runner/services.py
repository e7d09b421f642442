"""What a mission gives the tree's nodes beyond the vehicle, LSM and clock
(:data:`behaviors.registry.SERVICES`), built from the mission and its perception source."""

from __future__ import annotations

from typing import Any

from autonomy.perception.approach import MapApproachPlanner


class NoTerrainMap:
    """The approach planner of a mission whose detector builds no elevation map: it always
    says why, so the tree flies the thesis's climb, traverse and descent."""

    def __init__(self, detector: str) -> None:
        self.detector = detector

    def plan(self, start, goal) -> str:
        return f"no terrain map to plan over (the {self.detector} detector builds none)"


def service_names(mission: Any) -> frozenset[str]:
    """The services every flight of ``mission`` provides (what ``lander validate`` checks a
    tree file against)."""
    # Every mission has an approach planner: without a map it answers why not. The
    # descent's obstacle watch exists when the mission turns it on.
    names = {"approach_planner"}
    if mission.landing.descent_watch.enabled:
        names.add("obstacle_watch")
    return frozenset(names)


def build_services(mission: Any, source: Any, obstacle_watch: Any = None) -> dict[str, Any]:
    """The services for one flight: the approach planner over ``source``'s map where it has
    one, and the descent camera's ``obstacle_watch`` when the flight has one."""
    detector = getattr(source, "detector", None)
    elevation_map = getattr(detector, "map", None)
    if elevation_map is not None and hasattr(elevation_map, "top"):
        planner: Any = MapApproachPlanner(elevation_map, mission.landing.approach,
                                          default_margin=mission.landing.clear_altitude_buffer)
    else:
        planner = NoTerrainMap(mission.perception.detector)
    services: dict[str, Any] = {"approach_planner": planner}
    if obstacle_watch is not None:
        services["obstacle_watch"] = obstacle_watch
    return services
