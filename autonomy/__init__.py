"""Composition root: mission configuration, the MAVLink vehicle driver, clocks, the
mission runner, the ``lander`` command line, flight reports and campaigns."""

__version__ = "0.1.0"
