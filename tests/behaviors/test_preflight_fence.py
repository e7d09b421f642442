"""Preflight has the autopilot enforce the operating area when the mission uploads it: once
per flight, after the readiness checks, failing with the autopilot's reason."""

from __future__ import annotations

from py_trees.common import Status

from autonomy.clock import SimClock
from behaviors.flight import Preflight
from lsm.area import OperatingArea
from tests.behaviors.fakes import FakeVehicle

AREA = OperatingArea(((-50.0, -50.0), (50.0, -50.0), (50.0, 50.0), (-50.0, 50.0)), 2.0, 80.0)


def _tick(node: Preflight) -> Status:
    node.tick_once()
    return node.status


def test_the_area_is_uploaded_once_after_the_checks():
    vehicle = FakeVehicle(SimClock(), prearm_ok=False)
    node = Preflight("Preflight", vehicle, fence=AREA)
    assert _tick(node) is Status.RUNNING
    assert vehicle.commands == [], "nothing is sent before the vehicle is ready"
    vehicle.prearm_ok = True
    assert _tick(node) is Status.SUCCESS
    assert vehicle.commands == [("upload_fence", (AREA.vertices, 80.0))]
    assert _tick(node) is Status.SUCCESS  # re-entered: already on the autopilot
    assert len(vehicle.commands) == 1


def test_a_refused_upload_fails_with_the_autopilots_reason_and_is_tried_again_on_reentry():
    vehicle = FakeVehicle(SimClock(), deny={"upload_fence": "MISSION_ACK MAV_MISSION_ERROR"})
    node = Preflight("Preflight", vehicle, fence=AREA)
    assert _tick(node) is Status.FAILURE
    assert node.feedback_message == ("geofence not uploaded (denied): "
                                     "MISSION_ACK MAV_MISSION_ERROR")
    del vehicle.deny["upload_fence"]
    assert _tick(node) is Status.SUCCESS
    assert len(vehicle.commands) == 2


def test_without_a_fence_nothing_is_sent():
    vehicle = FakeVehicle(SimClock())
    assert _tick(Preflight("Preflight", vehicle)) is Status.SUCCESS
    assert vehicle.commands == []
