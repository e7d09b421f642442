"""The landing-site loss of the thesis (eq. 3.1); lower is better.

    L = w_dist * d / D + w_rough * roughness + w_var * uncertainty
        - w_size * size / size_max + w_verAlt * verification_altitude / D

d is the horizontal distance drone -> site, D the cruise altitude (the normaliser),
size_max the largest size currently retained (the size term is 0 while it is 0).
"""

from __future__ import annotations

import numpy as np

from lsm.settings import LossWeights


def site_loss(
    distance: np.ndarray,
    roughness: np.ndarray,
    uncertainty: np.ndarray,
    size: np.ndarray,
    verification_altitude: np.ndarray,
    size_max: float,
    weights: LossWeights,
) -> np.ndarray:
    """Loss of each site; all arrays of one shape (metres, or unitless in [0, 1]).

    Returns a float64 array of that shape.
    """
    d_norm = weights.normaliser
    size_term = np.asarray(size, dtype=np.float64) / size_max if size_max > 0 else 0.0
    return (
        weights.dist * np.asarray(distance, dtype=np.float64) / d_norm
        + weights.rough * np.asarray(roughness, dtype=np.float64)
        + weights.var * np.asarray(uncertainty, dtype=np.float64)
        - weights.size * size_term
        + weights.ver_alt * np.asarray(verification_altitude, dtype=np.float64) / d_norm
    )


def site_loss_scalar(
    distance: float,
    roughness: float,
    uncertainty: float,
    size: float,
    verification_altitude: float,
    size_max: float,
    weights: LossWeights,
) -> float:
    """The same loss for one site, in plain floats (the per-observation insert path)."""
    d_norm = weights.normaliser
    size_term = size / size_max if size_max > 0 else 0.0
    return (
        weights.dist * distance / d_norm
        + weights.rough * roughness
        + weights.var * uncertainty
        - weights.size * size_term
        + weights.ver_alt * verification_altitude / d_norm
    )
