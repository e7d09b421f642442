"""The live clock follows the vehicle's own time: at any speed-up, through silences and
reboots, never backwards."""

from __future__ import annotations

import random

import pytest

from autonomy.clock import VehicleClock


class Wall:
    def __init__(self) -> None:
        self.t = 1000.0

    def __call__(self) -> float:
        return self.t


def feed(clock: VehicleClock, wall: Wall, boot_time: float, seconds: float, speedup: float,
         rng: random.Random, readings: list[float]) -> float:
    """The vehicle runs ``seconds`` of its time at ``speedup``; the driver reads its stamps
    every 1/80 wall second, each up to 0.1 vehicle s old. Returns the vehicle's time."""
    step = 1.0 / 80.0
    for _ in range(round(seconds / (speedup * step))):
        wall.t += step
        boot_time += speedup * step
        clock.observe(boot_time - rng.uniform(0.0, 0.1))
        readings.append(clock.now())
    return boot_time


def test_before_the_vehicle_is_heard_the_clock_runs_at_wall_speed():
    wall = Wall()
    clock = VehicleClock(wall=wall)
    wall.t += 2.5
    assert clock.now() == pytest.approx(2.5)
    assert clock.rate == 1.0 and not clock.heard


@pytest.mark.parametrize("speedup", [1.0, 8.0, 40.0])
def test_durations_are_vehicle_seconds_at_any_speedup(speedup):
    wall, rng, readings = Wall(), random.Random(3), []
    clock = VehicleClock(wall=wall)
    boot = feed(clock, wall, 50.0, 20.0, speedup, rng, readings)  # settle
    start, start_boot = clock.now(), boot
    boot = feed(clock, wall, boot, 60.0, speedup, rng, readings)
    assert clock.now() - start == pytest.approx(boot - start_boot, abs=0.2)
    assert clock.rate == pytest.approx(speedup, rel=0.02)
    assert readings == sorted(readings)


def test_a_silent_vehicle_is_extrapolated_at_its_last_rate():
    wall, rng, readings = Wall(), random.Random(4), []
    clock = VehicleClock(wall=wall)
    feed(clock, wall, 10.0, 40.0, 8.0, rng, readings)
    before = clock.now()
    wall.t += 1.0  # nothing heard for a wall second
    assert clock.now() - before == pytest.approx(8.0, rel=0.02)


def test_a_reboot_or_a_pause_never_sets_the_clock_back():
    wall, rng, readings = Wall(), random.Random(5), []
    clock = VehicleClock(wall=wall)
    feed(clock, wall, 300.0, 40.0, 8.0, rng, readings)
    before = clock.now()
    boot = feed(clock, wall, 0.5, 40.0, 8.0, rng, readings)  # rebooted: time_boot_ms from 0
    assert readings == sorted(readings)
    assert clock.now() - before == pytest.approx(40.0, abs=0.5)
    # A simulator paused for 2 wall seconds: the clock extrapolated 16 s meanwhile, then
    # follows the vehicle again from where it stands.
    boot = feed(clock, wall, boot, 8.0, 8.0, rng, readings)
    wall.t += 2.0
    paused = clock.now()
    feed(clock, wall, boot, 16.0, 8.0, rng, readings)
    assert readings == sorted(readings)
    assert clock.now() - paused == pytest.approx(16.0, abs=0.5)
    assert clock.resyncs == 2
