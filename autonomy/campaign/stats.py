"""Confidence intervals for campaign success rates.

A success rate is a binomial proportion k/n; its interval is Wilson's score interval (scipy's
``binomtest(...).proportion_ci(method="wilson")``). Differences of success rates between two
missions flown with the same seeds are paired data, so their interval is Newcombe's hybrid
score ("square-and-add") interval for paired proportions (Newcombe 1998, Stat Med 17:2635,
method 10); :func:`newcombe_interval` is the independent-samples version (Newcombe 1998,
Stat Med 17:873, method 10).
"""

from __future__ import annotations

import math

from scipy.stats import binomtest

NAN_INTERVAL = (math.nan, math.nan)


def wilson_interval(successes: int, trials: int, confidence: float = 0.95) -> tuple[float, float]:
    """Wilson score interval ``(low, high)`` of the proportion ``successes / trials``.

    ``(nan, nan)`` when there are no trials.
    """
    if trials < 0 or not 0 <= successes <= max(trials, 0):
        raise ValueError(f"need 0 <= successes <= trials, got {successes}/{trials}")
    if trials == 0:
        return NAN_INTERVAL
    ci = binomtest(int(successes), int(trials)).proportion_ci(
        confidence_level=confidence, method="wilson"
    )
    return float(ci.low), float(ci.high)


def newcombe_interval(
    successes_a: int, trials_a: int, successes_b: int, trials_b: int, confidence: float = 0.95
) -> tuple[float, float]:
    """Interval of ``p_a - p_b`` for two independent proportions (hybrid Wilson score)."""
    if trials_a == 0 or trials_b == 0:
        return NAN_INTERVAL
    p_a, p_b = successes_a / trials_a, successes_b / trials_b
    l_a, u_a = wilson_interval(successes_a, trials_a, confidence)
    l_b, u_b = wilson_interval(successes_b, trials_b, confidence)
    d = p_a - p_b
    return (
        d - math.hypot(p_a - l_a, u_b - p_b),
        d + math.hypot(u_a - p_a, p_b - l_b),
    )


def newcombe_paired_interval(
    both: int, only_a: int, only_b: int, neither: int, confidence: float = 0.95
) -> tuple[float, float]:
    """Interval of ``p_a - p_b`` for paired proportions (Newcombe's square-and-add, method 10).

    The pairs form the 2x2 table ``[[both, only_a], [only_b, neither]]``: ``both`` pairs
    succeeded under A and B, ``only_a`` under A only, and so on, so that
    ``p_a = (both + only_a) / n`` and ``p_b = (both + only_b) / n``. The Wilson intervals of
    the two margins are combined with the continuity-corrected phi correlation of the pairs.
    """
    n = both + only_a + only_b + neither
    if n == 0:
        return NAN_INTERVAL
    s_a, s_b = both + only_a, both + only_b
    p_a, p_b = s_a / n, s_b / n
    l_a, u_a = wilson_interval(s_a, n, confidence)
    l_b, u_b = wilson_interval(s_b, n, confidence)
    margins = s_a * (n - s_a) * s_b * (n - s_b)
    phi = 0.0
    if margins > 0:
        cross = both * neither - only_a * only_b
        if cross > n / 2:
            phi = (cross - n / 2) / math.sqrt(margins)
        elif cross < 0:
            phi = cross / math.sqrt(margins)
    d = p_a - p_b
    da_lo, da_hi, db_lo, db_hi = p_a - l_a, u_a - p_a, p_b - l_b, u_b - p_b
    low = d - math.sqrt(max(da_lo**2 + db_hi**2 - 2 * phi * da_lo * db_hi, 0.0))
    high = d + math.sqrt(max(db_lo**2 + da_hi**2 - 2 * phi * db_lo * da_hi, 0.0))
    return max(low, -1.0), min(high, 1.0)
