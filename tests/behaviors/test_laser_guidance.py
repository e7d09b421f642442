"""LaserGuidance on its own: a point-mass vehicle flown by velocity, reading the SITL's
light-sensor model, guided to the emitter and landed, or giving up with a reason."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import py_trees
import pytest
from py_trees.common import Status

from autonomy.clock import SimClock
from behaviors import blackboard as keys
from behaviors.laser_guidance import LaserGuidance, LaserGuidanceSettings
from behaviors.ports import CommandStatus, LandedState, VehicleState
from sitl.sensors.laser import LaserSettings, LightSensorRing

DT = 0.1


class Handle:
    def __init__(self, name, status=CommandStatus.ACCEPTED, reason=""):
        self.name, self.status, self.reason = name, status, reason


def flat(x, y):
    return np.zeros(np.broadcast(np.asarray(x), np.asarray(y)).shape)


class LightVehicle:
    """Flies the commanded ENU velocity exactly and reads the light-sensor ring every step
    (None: no laser at all). Its yaw is fixed at ``yaw``."""

    def __init__(self, clock, ring, position=(0.0, 0.0, 40.0), yaw=0.7, deny=()):
        self.clock, self.ring = clock, ring
        self.position = position
        self.yaw = yaw  # ENU rad
        self.velocity = (0.0, 0.0, 0.0)
        self.armed, self.mode = True, "GUIDED"
        self.deny = set(deny)
        self.commands: list[tuple] = []
        self.mask, self.mask_time = None, None

    @property
    def state(self):
        x, y, z = self.position
        landed = LandedState.ON_GROUND if z <= 0.0 else LandedState.IN_AIR
        return VehicleState(
            time=self.clock.now(), position=None, yaw=self.yaw, armed=self.armed,
            mode=self.mode, landed_state=landed, battery_percent=80.0, gps_fix=1,
            rangefinder_agl=z, heartbeat_age=0.0, link_lost=False,
            light_sensors=self.mask, light_sensors_time=self.mask_time,
        )  # fmt: skip

    def set_velocity(self, vx, vy, vz):
        self.commands.append(("set_velocity", vx, vy, vz))
        if "set_velocity" in self.deny:
            return Handle("set_velocity", CommandStatus.DENIED, "Mode change to GUIDED failed")
        self.velocity, self.mode = (vx, vy, vz), "GUIDED"
        return Handle("set_velocity")

    def step(self):
        x, y, z = self.position
        vx, vy, vz = self.velocity
        self.position = (x + vx * DT, y + vy * DT, max(z + vz * DT, 0.0))
        self.clock.advance(DT)
        if self.ring is not None:
            heading = math.pi / 2 - self.yaw  # compass heading, clockwise from north
            self.mask, self.mask_time = self.ring.read(self.position, heading), self.clock.now()


def fly(vehicle, behaviour, seconds):
    tree = py_trees.trees.BehaviourTree(behaviour)
    tree.setup()
    status = Status.RUNNING
    for _ in range(round(seconds / DT)):
        vehicle.step()
        tree.tick()
        status = behaviour.status
        if status != Status.RUNNING:
            break
    return status


@pytest.fixture
def mission():
    keys.reset()
    keys.initialise()


def ring(emitter, seed=0, **kwargs):
    settings = LaserSettings(
        **{"emitter": emitter, "condition": "night", "reflection_rate": 0.05, **kwargs}
    )
    return LightSensorRing(settings, flat, np.random.default_rng(seed))


@pytest.mark.parametrize("emitter", [(120.0, -60.0), (-80.0, 90.0)])
def test_follows_the_laser_and_lands_over_the_emitter(mission, emitter):
    clock = SimClock()
    vehicle = LightVehicle(clock, ring(emitter))
    guidance = LaserGuidance("Laser guidance", vehicle, clock, rng=np.random.default_rng(1))
    assert fly(vehicle, guidance, 300.0) == Status.SUCCESS
    x, y, z = vehicle.position
    # Over the emitter at the hand-over height: the downward sensor sees it within 15 deg.
    assert z <= 3.0
    assert math.hypot(x - emitter[0], y - emitter[1]) <= z * math.tan(math.radians(15.0))
    assert vehicle.commands[0] == ("set_velocity", 0.0, 0.0, 0.0)  # hovers first
    assert vehicle.commands[-1][3] < 0.0  # the last command descended
    # Ticked again, it stays done and commands nothing.
    before = len(vehicle.commands)
    assert fly(vehicle, guidance, 1.0) == Status.SUCCESS
    assert len(vehicle.commands) == before


def test_a_vehicle_without_light_sensors_gives_up_at_once(mission):
    clock = SimClock()
    vehicle = LightVehicle(clock, None)
    guidance = LaserGuidance("Laser guidance", vehicle, clock)
    assert fly(vehicle, guidance, 1.0) == Status.FAILURE
    assert clock.now() == pytest.approx(DT)
    assert vehicle.commands == []
    reason = py_trees.blackboard.Blackboard.get(keys.FAILURE_REASON)
    assert reason == "Laser guidance: no light sensors report on this vehicle"


def test_without_a_laser_it_hovers_then_gives_up_for_good(mission):
    clock = SimClock()
    vehicle = LightVehicle(clock, ring(None, reflection_rate=0.0))
    settings = LaserGuidanceSettings(wait_timeout=10.0)
    guidance = LaserGuidance("Laser guidance", vehicle, clock, settings)
    assert fly(vehicle, guidance, 30.0) == Status.FAILURE
    assert 10.0 < clock.now() < 10.5
    assert {c for c in vehicle.commands} == {("set_velocity", 0.0, 0.0, 0.0)}
    reason = py_trees.blackboard.Blackboard.get(keys.FAILURE_REASON)
    assert reason == "Laser guidance: no laser within 10 s"
    # Ticked again (the tree re-enters it), it fails at once and commands nothing, even
    # when a laser turns up.
    vehicle.ring = ring((50.0, 0.0))
    before = len(vehicle.commands)
    assert fly(vehicle, guidance, 5.0) == Status.FAILURE
    assert len(vehicle.commands) == before


def test_only_reflections_never_make_it_fly(mission):
    clock = SimClock()
    # An emitter far beyond the laser's reach: the sensors see reflections only.
    vehicle = LightVehicle(clock, ring((30_000.0, 0.0), reflection_rate=0.3))
    guidance = LaserGuidance(
        "Laser guidance", vehicle, clock, LaserGuidanceSettings(wait_timeout=20.0)
    )
    status = fly(vehicle, guidance, 40.0)
    flown = [c for c in vehicle.commands if c[0] == "set_velocity" and any(c[1:])]
    # Readings from random sectors never agree for long: no bearing is flown.
    assert flown == []
    assert status == Status.FAILURE
    assert py_trees.blackboard.Blackboard.get(keys.FAILURE_REASON).endswith(
        "no laser within 20 s"
    )


def test_laser_behind_terrain_hovers_then_gives_up(mission):
    clock = SimClock()
    beam = ring((100.0, 0.0))
    vehicle = LightVehicle(clock, beam)
    settings = LaserGuidanceSettings(lost_timeout=8.0)
    guidance = LaserGuidance("Laser guidance", vehicle, clock, settings)
    assert fly(vehicle, guidance, 8.0) == Status.RUNNING  # flying toward it
    assert vehicle.velocity[0] > 2.0
    beam.height = lambda x, y: np.full(np.broadcast(np.asarray(x), np.asarray(y)).shape, 80.0)
    assert fly(vehicle, guidance, 20.0) == Status.FAILURE
    assert vehicle.velocity == (0.0, 0.0, 0.0)  # hovered while it waited
    assert "laser lost for" in py_trees.blackboard.Blackboard.get(keys.FAILURE_REASON)


def test_a_denied_velocity_command_gives_up_with_the_autopilots_reason(mission):
    clock = SimClock()
    vehicle = LightVehicle(clock, ring((50.0, 0.0)), deny={"set_velocity"})
    guidance = LaserGuidance("Laser guidance", vehicle, clock)
    assert fly(vehicle, guidance, 5.0) == Status.FAILURE
    assert "Mode change to GUIDED failed" in py_trees.blackboard.Blackboard.get(
        keys.FAILURE_REASON
    )


def test_settings_refuse_what_cannot_fly():
    with pytest.raises(ValueError):
        LaserGuidanceSettings(speed=0.0)
    with pytest.raises(ValueError):
        LaserGuidanceSettings(dispersion=1.0)


# ------------------------------------------------------------------ in the mission tree
def _tree_mission(landing, light_sensors=True):
    from behaviors_fakes import FakeVehicle

    class RingVehicle(FakeVehicle):
        """The behaviour tests' fake with a light-sensor ring that never sees a laser."""

        @property
        def state(self):
            state = super().state
            if not light_sensors:
                return state
            return dataclasses.replace(
                state, light_sensors=0, light_sensors_time=self.clock.now()
            )

    from behaviors.settings import LandingSettings, MissionPlan
    from behaviors.tree import build_mission_tree
    from lsm import LandingSiteManager, LsmSettings

    plan = MissionPlan(
        waypoints=[(0, 0, 50), (300, 0, 50)], landing=LandingSettings.model_validate(landing)
    )
    clock = SimClock()
    vehicle = RingVehicle(clock)
    lsm = LandingSiteManager(LsmSettings())
    tree = build_mission_tree(plan, vehicle, lsm, clock, np.random.default_rng(0))
    return clock, vehicle, lsm, tree


def _lose_gps_at(vehicle, x):
    def on_tick(_):
        if vehicle.position[0] >= x:
            vehicle.gps_fix = 1

    return on_tick


def test_in_the_tree_no_laser_hovers_its_wait_then_lands_in_place():
    from behaviors_fakes import fly as fly_mission

    landing = {"gps_loss_timeout": 2.0, "laser_guidance": {"wait_timeout": 12.0}}
    clock, vehicle, lsm, tree = _tree_mission(landing)
    flight = fly_mission(tree, vehicle, clock, lsm, on_tick=_lose_gps_at(vehicle, 100.0))
    assert flight.status == Status.SUCCESS
    names = [name for name, _ in vehicle.commands]
    hover = names.index("set_velocity")
    assert vehicle.commands[hover] == ("set_velocity", (0.0, 0.0, 0.0))
    assert names[hover + 1 :] == ["land"]  # nothing flown on no evidence, then in place
    assert py_trees.blackboard.Blackboard.get(keys.OUTCOME_HINT) == "gps_lost"


def test_in_the_tree_a_vehicle_without_light_sensors_lands_in_place_at_once():
    from behaviors_fakes import fly as fly_mission

    clock, vehicle, lsm, tree = _tree_mission({"gps_loss_timeout": 2.0}, light_sensors=False)
    flight = fly_mission(tree, vehicle, clock, lsm, on_tick=_lose_gps_at(vehicle, 100.0))
    assert flight.status == Status.SUCCESS
    names = [name for name, _ in vehicle.commands]
    assert "set_velocity" not in names and names[-1] == "land"
    assert py_trees.blackboard.Blackboard.get(keys.OUTCOME_HINT) == "gps_lost"


def test_in_the_tree_a_critical_battery_cuts_the_guidance_short():
    from behaviors_fakes import fly as fly_mission

    landing = {"gps_loss_timeout": 2.0, "laser_guidance": {"wait_timeout": 600.0}}
    clock, vehicle, lsm, tree = _tree_mission(landing)
    lose = _lose_gps_at(vehicle, 100.0)
    hovering_since: list[float] = []

    def on_tick(tick):
        lose(tick)
        if any(name == "set_velocity" for name, _ in vehicle.commands):
            hovering_since.append(clock.now())
            if clock.now() - hovering_since[0] > 20.0:
                vehicle.battery = 10.0  # below the critical 15 %

    flight = fly_mission(tree, vehicle, clock, lsm, on_tick=on_tick)
    assert flight.status == Status.SUCCESS
    assert vehicle.commands[-1][0] == "land"
    assert 20.0 < clock.now() - hovering_since[0] < 60.0  # not the 600 s wait
