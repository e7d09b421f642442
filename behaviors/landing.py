"""Landing-site behaviours (thesis section 3.3.1): check, choose, clear altitude, verify."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

from py_trees.common import Access, Status

from behaviors import blackboard as keys
from behaviors.base import MissionBehaviour, VehicleAction, horizontal_distance
from behaviors.ports import Clock, VehiclePort
from lsm.area import OperatingArea
from lsm.records import LandingSite

if TYPE_CHECKING:
    from lsm import LandingSiteManager


def clear_altitude(
    site: LandingSite,
    drone_position: Sequence[float],
    buffer: float,
    failsafe_altitude: float,
) -> float:
    """Clear altitude for flying to ``site`` (thesis eq. 3.4-3.5), ENU z in m.

    ``z_clear = min(z_obst + z_buffer + d_drone-LS, z_failsafe)``: the obstacle altitude
    around the site plus a buffer, plus the horizontal drone-site distance (worst case,
    terrain rising at 45 degrees from the site towards the drone), capped at the failsafe
    altitude.

    Args:
        site: the landing site (its ``obstacle_altitude`` and x, y are used).
        drone_position: ENU x, y[, z] of the drone, m.
        buffer: z_buffer, m >= 0.
        failsafe_altitude: z_failsafe, the cap, m.
    """
    distance = horizontal_distance(drone_position, (site.x, site.y))
    return min(site.obstacle_altitude + buffer + distance, failsafe_altitude)


class CheckLandingSite(MissionBehaviour):
    """Condition: the LSM holds at least one landing site.

    * SUCCESS: at least one site retained
    * FAILURE: none
    """

    def __init__(self, name: str, lsm: LandingSiteManager) -> None:
        super().__init__(name, phase="landing_phase")
        self.lsm = lsm

    def update(self) -> Status:
        count = len(self.lsm)
        self.feedback_message = f"{count} site(s) known"
        return Status.SUCCESS if count else Status.FAILURE


class GetClearAltitude(MissionBehaviour):
    """Compute the clear altitude for the chosen site from the vehicle position and write it
    to CLEAR_ALTITUDE.

    * SUCCESS: written
    * FAILURE: no site chosen or vehicle position unknown
    """

    def __init__(
        self, name: str, vehicle: VehiclePort, *, buffer: float, failsafe_altitude: float,
        site_key: str = keys.LANDING_SITE, clear_altitude_key: str = keys.CLEAR_ALTITUDE,
    ) -> None:
        super().__init__(name)
        self.vehicle = vehicle
        self.buffer = float(buffer)
        self.failsafe_altitude = float(failsafe_altitude)
        self.site_key = site_key
        self.clear_altitude_key = clear_altitude_key
        self.blackboard.register_key(key=site_key, access=Access.READ)
        self.blackboard.register_key(key=clear_altitude_key, access=Access.WRITE)

    def update(self) -> Status:
        site = self.blackboard.get(self.site_key)
        position = self.vehicle.state.position
        if site is None:
            return self.fail("no landing site chosen")
        if position is None:
            return self.fail("vehicle position unknown")
        z_clear = clear_altitude(site, position, self.buffer, self.failsafe_altitude)
        self.blackboard.set(self.clear_altitude_key, z_clear)
        self.feedback_message = f"clear altitude {z_clear:.1f} m"
        return Status.SUCCESS


class GetLandingSite(MissionBehaviour):
    """Choose the best site (lowest loss at the drone position) and its clear altitude.

    With ``verified_only``, only verified sites (``lsm.is_verified``: re-detected from the
    verification altitude) are candidates: the last resort once the landing tries are spent.

    Writes LANDING_SITE and CLEAR_ALTITUDE (:func:`clear_altitude`).

    With an operating ``area`` (the LSM keeps only sites inside it), the chosen site is the
    best one the approach reaches inside the area: the climb and descent are vertical, so
    the traverse, a straight leg from the vehicle to the site, must stay inside (a
    non-convex area can have both ends inside and the leg out; a leg across one of its
    no-fly zones counts as out). Sites it would leave by are passed over (not banned: from
    elsewhere the leg may be inside).

    * SUCCESS: a site was chosen
    * FAILURE: the LSM holds no (verified) site, none with a straight leg inside the area,
      or the vehicle position is unknown
    """

    def __init__(
        self,
        name: str,
        vehicle: VehiclePort,
        lsm: LandingSiteManager,
        *,
        buffer: float,
        failsafe_altitude: float,
        verified_only: bool = False,
        site_key: str = keys.LANDING_SITE,
        clear_altitude_key: str = keys.CLEAR_ALTITUDE,
        area: OperatingArea | None = None,
    ) -> None:
        super().__init__(name, phase="landing_phase")
        self.vehicle = vehicle
        self.lsm = lsm
        self.area = area
        self.buffer = float(buffer)
        self.failsafe_altitude = float(failsafe_altitude)
        self.verified_only = verified_only
        self.site_key = site_key
        self.clear_altitude_key = clear_altitude_key
        self.blackboard.register_key(key=site_key, access=Access.WRITE)
        self.blackboard.register_key(key=clear_altitude_key, access=Access.WRITE)

    def update(self) -> Status:
        position = self.vehicle.state.position
        if position is None:
            return self.fail("vehicle position unknown")
        if self.area is not None:
            return self._choose_inside(position, self.area)
        best = self.lsm.best_verified if self.verified_only else self.lsm.best
        site = best(position)
        if site is None:
            return self.fail(f"no {'verified ' if self.verified_only else ''}landing site known")
        return self._choose(site, position)

    def _choose_inside(self, position: Sequence[float], area: OperatingArea) -> Status:
        ranking = self.lsm.ranked(position)
        candidates = range(len(ranking))
        if self.verified_only:
            candidates = [i for i in candidates if self.lsm.is_verified(ranking[i])]
        if not candidates:
            return self.fail(f"no {'verified ' if self.verified_only else ''}landing site known")
        for i in candidates:
            site = ranking[i]
            if area.leg_inside(position, (site.x, site.y)):
                return self._choose(site, position)
        return self.fail("no site reachable by a straight leg inside the geofence")

    def _choose(self, site: LandingSite, position: Sequence[float]) -> Status:
        z_clear = clear_altitude(site, position, self.buffer, self.failsafe_altitude)
        self.blackboard.set(self.site_key, site)
        self.blackboard.set(self.clear_altitude_key, z_clear)
        self.feedback_message = (
            f"site {site.id} at ({site.x:.1f}, {site.y:.1f}, {site.z:.1f}), "
            f"loss {site.loss:.3f}, clear altitude {z_clear:.1f} m"
        )
        return Status.SUCCESS


class LandingSiteVerification(VehicleAction):
    """Hover over the chosen site for ``duration`` clock seconds waiting for the LSM to
    show it re-detected at low altitude (``lsm.is_verified``).

    The chosen site is the LSM record with the same id or, if that one is gone, a retained
    site within ``match_radius`` (horizontal) of where it was last. Low looks replace the
    record's position and height by better ones, so the hover follows the record: when it
    has moved more than ``recentre_distance`` from the hover point (horizontally, or in
    height), the vehicle is sent to ``height`` m above the record's new position. Without
    this the vehicle would keep hovering where the high-altitude estimate put the site, and
    the camera would not see the whole footprint of the site it is meant to verify.
    On success the fresh record replaces LANDING_SITE; on failure the site is banned
    (``lsm.ban``) so that high-altitude detections of it are rejected from now on.

    With ``fresh`` only a re-detection during this hover counts (``last_seen`` since it
    began): a site seen low before, e.g. on takeoff, may since have been walked onto.

    * SUCCESS: the chosen site is verified
    * FAILURE: not verified within ``duration`` (site banned), no site chosen, or a
      re-centring goto denied / unanswered
    * RUNNING: hovering
    """

    def __init__(
        self,
        name: str,
        vehicle: VehiclePort,
        lsm: LandingSiteManager,
        clock: Clock,
        *,
        duration: float,
        match_radius: float,
        height: float,
        recentre_distance: float = 0.5,
        command_timeout: float = 5.0,
        site_key: str = keys.LANDING_SITE,
        fresh: bool = False,
    ) -> None:
        super().__init__(
            name, vehicle, clock, command_timeout=command_timeout, phase="verification"
        )
        self.fresh = bool(fresh)
        self.started = 0.0
        self.lsm = lsm
        self.duration = float(duration)
        self.match_radius = float(match_radius)
        self.height = float(height)
        self.recentre_distance = float(recentre_distance)
        self.deadline = 0.0
        self.site: LandingSite | None = None
        self.hover: tuple[float, float, float] | None = None
        self.recentred = 0
        self.site_key = site_key
        self.blackboard.register_key(key=site_key, access=Access.WRITE)
        self.blackboard.register_key(key=keys.VERIFICATION_ATTEMPTS, access=Access.WRITE)
        self.blackboard.register_key(key=keys.BANNED_SITES, access=Access.WRITE)

    def initialise(self) -> None:
        super().initialise()
        self.site = self.blackboard.get(self.site_key)
        self.started = self.clock.now()
        self.deadline = self.started + self.duration
        # The descent flew to this point above the site as chosen.
        self.hover = None if self.site is None else self._above(self.site)
        self.recentred = 0
        attempts = self.blackboard.get(keys.VERIFICATION_ATTEMPTS)
        self.blackboard.set(keys.VERIFICATION_ATTEMPTS, attempts + 1)

    def _above(self, site: LandingSite) -> tuple[float, float, float]:
        return (site.x, site.y, site.z + self.height)

    def current_record(self) -> LandingSite | None:
        """The LSM's record of the chosen site now (same id, else the nearest in match
        radius of where it was last), or None."""
        site = self.site
        assert site is not None
        record = self.lsm.get(site.id)
        if record is not None:
            return record
        nearest, best = None, self.match_radius
        for candidate in self.lsm.ranked():
            distance = horizontal_distance(candidate.position, site.position)
            if distance <= best:
                nearest, best = candidate, distance
        return nearest

    def _follow(self, record: LandingSite) -> None:
        """Send the vehicle above ``record`` if the record moved away from the hover point."""
        target = self._above(record)
        hover = self.hover
        if hover is not None and (
            horizontal_distance(target, hover) <= self.recentre_distance
            and abs(target[2] - hover[2]) <= self.recentre_distance
        ):
            return
        self.command(self.vehicle.goto(*target))
        self.hover = target
        self.recentred += 1

    def update(self) -> Status:
        if self.site is None:
            return self.fail("no landing site chosen")
        problem = self.command_problem()
        if problem is not None:
            return self.fail(problem)
        record = self.current_record()
        if record is not None and self.lsm.is_verified(record) and (
                not self.fresh or record.last_seen >= self.started):
            self.blackboard.set(self.site_key, record)
            self.feedback_message = (
                f"site {record.id} verified (seen from {record.verification_altitude:.1f} m)"
            )
            return Status.SUCCESS
        remaining = self.deadline - self.clock.now()
        if remaining > 0:
            if record is not None:
                self.site = record  # follow the record as low looks move it
                self._follow(record)
            moved = f", re-centred {self.recentred}x" if self.recentred else ""
            self.feedback_later("waiting for re-detection, {:.1f} s left{}", remaining, moved)
            return Status.RUNNING
        banned = record is not None and self.lsm.ban(record.id)
        if banned:
            self.blackboard.set(keys.BANNED_SITES, self.blackboard.get(keys.BANNED_SITES) + 1)
        outcome = "banned" if banned else "no longer retained, not banned"
        return self.fail(
            f"site {self.site.id} not re-detected within {self.duration:g} s ({outcome})"
        )
