"""Perception in the loop: sources that turn what the vehicle senses into site observations.

A source satisfies :class:`autonomy.perception.base.SiteSource`; the runner calls it at the
perception rate and submits what it returns to the Landing Site Manager.
"""

from autonomy.perception.base import SiteSource

__all__ = ["SiteSource"]
