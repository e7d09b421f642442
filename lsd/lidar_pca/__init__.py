"""The LiDAR PCA landing-spot detector (Loureiro et al. 2021): the plane search
(:mod:`lsd.lidar_pca.detector`), its settings (:mod:`lsd.lidar_pca.settings`), site rules on
classified clouds (:mod:`lsd.lidar_pca.sites`), tiles for clouds larger than memory
(:mod:`lsd.lidar_pca.tiles`), and judging sites against a cloud's labels
(:mod:`lsd.lidar_pca.judge`)."""

from lsd.lidar_pca.detector import *  # noqa: F403
from lsd.lidar_pca.detector import __all__  # noqa: F401
