"""The depth-image costmap detector (Mittal et al., eq. 1-7): costmaps, dense sites and their
clustering (:mod:`lsd.depth_costmap.detector`), with its settings
(:mod:`lsd.depth_costmap.settings`)."""

from lsd.depth_costmap.detector import *  # noqa: F403
from lsd.depth_costmap.detector import __all__  # noqa: F401
