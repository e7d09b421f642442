"""GPS-denied guidance: estimators that steer a vehicle without a position fix.

A leaf package (numpy only): it imports nothing else of the project, so a companion
computer can run it on its own.
"""

from guidance.direction import DirectionEstimatorSettings, GuidingDirectionEstimator

__all__ = ["DirectionEstimatorSettings", "GuidingDirectionEstimator"]
