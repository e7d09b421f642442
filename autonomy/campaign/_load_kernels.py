"""Imported by a local pool's fork server after the flight stack: loads the cached compiled
kernels of every module imported so far (:func:`autonomy.campaign.warm.load_cached_kernels`),
so the workers it forks start with them."""

from autonomy.campaign.warm import load_cached_kernels

load_cached_kernels()
