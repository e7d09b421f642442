"""Site sizes from the distance transform of the safe mask: exact and reproducible."""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from lsd.site_selection import site_size


def test_site_size_is_the_exact_distance_and_the_same_on_every_call():
    rng = np.random.default_rng(4)
    safe = rng.random((160, 120)) < 0.97
    resolution = 0.25
    sizes = [site_size(safe, resolution) for _ in range(30)]
    # Equal bit for bit from call to call, so that ties between sites break the same way.
    assert all(np.array_equal(sizes[0], s) for s in sizes[1:])
    exact = np.maximum(ndimage.distance_transform_edt(safe) - 0.5, 0.0) * resolution
    np.testing.assert_allclose(sizes[0], exact, atol=1e-5)
