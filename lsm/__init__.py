"""Landing Site Manager: site records, the landing-site loss, ranking, redetection and bans.

A leaf package: it imports nothing from the rest of the project. Detectors submit
:class:`SiteObservation` records; the manager keeps the best :class:`LandingSite` records
in a bounded max-heap ranked by the thesis loss (eq. 3.1).
"""

from lsm.records import LandingSite, SiteObservation

__all__ = ["LandingSite", "SiteObservation"]
