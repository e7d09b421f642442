"""The driver reads the laser light-sensor ring (NAMED_VALUE_INT LASER_RING) and the GPS
fix into VehicleState (docs/gps-denied.md)."""

from pymavlink.dialects.v20 import ardupilotmega as mavlink

GUIDED = 4


def test_light_sensor_readings_become_state_with_their_arrival_time(rig):
    peer = rig.peer
    peer.heartbeat(custom_mode=GUIDED, armed=True)
    s = rig.tick()
    assert s.light_sensors is None and s.light_sensors_time is None
    peer.send(peer.mav.named_value_int_encode(100, b"LASER_RING", (1 << 3) | (1 << 12)))
    peer.send(peer.mav.named_value_int_encode(100, b"RPM", 5000))  # someone else's value
    s = rig.tick()
    assert s.light_sensors == (1 << 3) | (1 << 12)
    assert s.light_sensors_time == rig.clock.now()
    first = s.light_sensors_time
    rig.run(0.5)
    assert rig.vehicle.state.light_sensors_time == first  # nothing new arrived
    peer.send(peer.mav.named_value_int_encode(200, b"LASER_RING", 1 << 20))  # no such sensor
    s = rig.tick()
    assert s.light_sensors == (1 << 3) | (1 << 12)
    assert rig.vehicle.stats.dropped_sensor["LASER_RING"] == 1


def test_a_lost_fix_shows_in_the_state(rig):
    peer = rig.peer
    peer.heartbeat(custom_mode=GUIDED, armed=True)
    peer.send(peer.mav.gps_raw_int_encode(0, 3, 0, 0, 0, 0, 0, 0, 0, 10))
    assert rig.tick().gps_fix == 3
    peer.send(peer.mav.gps_raw_int_encode(0, mavlink.GPS_FIX_TYPE_NO_FIX, 0, 0, 0, 65535,
                                          65535, 0, 0, 0))
    assert rig.tick().gps_fix == mavlink.GPS_FIX_TYPE_NO_FIX
