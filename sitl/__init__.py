"""The embedded simulator: terrain worlds, sensors, a kinematic multicopter and its
MAVLink server. A separate "vehicle": it never imports :mod:`autonomy` or :mod:`behaviors`."""
