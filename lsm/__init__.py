"""Landing Site Manager: site records, the landing-site loss, ranking, redetection and bans.

A leaf package: it imports nothing from the rest of the project. Detectors submit
:class:`SiteObservation` records; the :class:`LandingSiteManager` keeps the best
:class:`LandingSite` records in a bounded max-heap ranked by the thesis loss (eq. 3.1).
"""

from lsm.area import OperatingArea
from lsm.loss import site_loss
from lsm.manager import Decision, LandingSiteManager, LsmSnapshot, RankedSites
from lsm.records import LandingSite, SiteObservation
from lsm.settings import LossWeights, LsmSettings

__all__ = [
    "Decision",
    "LandingSite",
    "LandingSiteManager",
    "LossWeights",
    "LsmSettings",
    "LsmSnapshot",
    "OperatingArea",
    "RankedSites",
    "SiteObservation",
    "site_loss",
]
