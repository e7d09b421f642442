"""Approach planning: a collision-free path over what the vehicle knows of the terrain, and a
minimum-snap trajectory through it (Mittal, Valada and Burgard, section III-D).

A leaf package: numpy and scipy only, no other package of the project. Positions are local
ENU metres, times seconds, grids indexed ``[i, j]`` with axis 0 along x (east) and axis 1
along y (north), as :mod:`lsd.elevation.map` lays them out.
"""

from planning.approach import ApproachPlan, plan_approach
from planning.clearance import clearance_grid
from planning.grid_path import GridPath, free_cells, plan_path
from planning.min_snap import Trajectory, min_snap_trajectory

__all__ = [
    "ApproachPlan",
    "GridPath",
    "Trajectory",
    "clearance_grid",
    "free_cells",
    "min_snap_trajectory",
    "plan_approach",
    "plan_path",
]
