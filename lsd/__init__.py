"""Landing-site detection: turns sensor data (depth images, point clouds) into
:class:`lsm.SiteObservation` records. Imports only :mod:`lsm`."""
