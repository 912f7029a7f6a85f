"""The statistics of the results table: how sure a success rate is, and whether two agents differ.

A benchmark split holds tens to hundreds of episodes per task type, so a rate alone says little: 3 of 4 and 75 of
100 are both 75%. ``wilson`` gives the 95% score interval of a rate (good at small n and at rates of 0 or 1, where
the normal approximation gives intervals outside [0, 1] or of width zero). ``mcnemar_exact`` tests two agents run
on the same episodes, using only the episodes where exactly one of them succeeded; it is exact (a binomial test),
so it holds for the handful of discordant episodes a small split gives.

Both are written with integer arithmetic (``math.comb``): exact for any count, with no statistics library to load
(scipy's ``binomtest`` gives the same p-values; the tests check it).
"""
from __future__ import annotations

import math

# The two-sided 95% normal quantile.
Z95 = 1.959964


def wilson(successes: int, n: int, z: float = Z95) -> tuple[float, float]:
    """The Wilson score interval ``(low, high)`` of the rate ``successes / n``; ``(0.0, 1.0)`` when ``n == 0``
    (no episode: nothing is known)."""
    if not 0 <= successes <= n:
        raise ValueError(f"successes must be in [0, n], got {successes} of {n}")
    if n == 0:
        return 0.0, 1.0
    p = successes / n
    z2 = z * z
    centre = (p + z2 / (2 * n)) / (1 + z2 / n)
    half = z / (1 + z2 / n) * math.sqrt(p * (1 - p) / n + z2 / (4 * n * n))
    # At 0 and n successes one bound is exactly 0 or 1; the formula gives it up to rounding.
    low = 0.0 if successes == 0 else max(0.0, centre - half)
    high = 1.0 if successes == n else min(1.0, centre + half)
    return low, high


def mcnemar_exact(b: int, c: int) -> float:
    """The two-sided exact McNemar p-value of ``b`` episodes only the first agent solved and ``c`` only the second
    did: under "no difference" each discordant episode is a fair coin, so p = min(1, 2 P(X <= min(b, c))) with
    X ~ Binomial(b + c, 1/2). ``1.0`` when there is no discordant episode."""
    if b < 0 or c < 0:
        raise ValueError(f"discordant counts must be >= 0, got b={b}, c={c}")
    n = b + c
    if n == 0:
        return 1.0
    tail = sum(math.comb(n, k) for k in range(min(b, c) + 1))
    return min(1.0, 2 * tail / 2 ** n)  # int / int: correctly rounded however large the counts


def quantile(values: list[float], q: float) -> float | None:
    """The ``q`` quantile (0 <= q <= 1) of ``values`` by linear interpolation between the closest ranks (numpy's
    default, Hyndman and Fan's type 7): the median of 1, 2, 3, 10 is 2.5; None for no values."""
    if not 0.0 <= q <= 1.0:
        raise ValueError(f"q must be in [0, 1], got {q}")
    if not values:
        return None
    ordered = sorted(values)
    position = q * (len(ordered) - 1)
    low = math.floor(position)
    high = min(low + 1, len(ordered) - 1)
    return ordered[low] + (ordered[high] - ordered[low]) * (position - low)
