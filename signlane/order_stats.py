"""np.median and np.percentile (its default, linear method: the same floats) without their
per-call overhead: the library calls cost 50-100 us apiece in wrappers, and the lane and sign
stages call them tens of times a frame on small arrays."""
from __future__ import annotations

import numpy as np


def sorted_quantile(ordered: np.ndarray, q: float) -> float:
    """np.percentile(values, 100 q) of already sorted, non-empty values."""
    pos = q * (len(ordered) - 1)
    lo = int(pos)
    hi = min(lo + 1, len(ordered) - 1)
    return float(ordered[lo]) + (float(ordered[hi]) - float(ordered[lo])) * (pos - lo)


def sorted_median(ordered: np.ndarray) -> float:
    """np.median of already sorted, non-empty values (the mean of the middle two when even)."""
    n = len(ordered)
    return float(ordered[n // 2]) if n % 2 else (float(ordered[n // 2 - 1]) + float(ordered[n // 2])) / 2.0


def median(values: np.ndarray) -> float:
    """np.median of non-empty 1-D values."""
    return sorted_median(np.sort(values))


def quantile(values: np.ndarray, q: float) -> float:
    """np.percentile(values, 100 q) of non-empty 1-D values, from a partial sort (two order
    statistics) rather than a full one."""
    n = len(values)
    pos = q * (n - 1)
    lo = int(pos)
    hi = min(lo + 1, n - 1)
    part = np.partition(values, (lo, hi) if hi != lo else lo)
    return float(part[lo]) + (float(part[hi]) - float(part[lo])) * (pos - lo)


def median_rows(values: np.ndarray) -> np.ndarray:
    """np.median(values, axis=0) of a non-empty 2-D integer array (float64, as numpy gives):
    a colour patch's median colour."""
    n = len(values)
    part = np.partition(values, (n - 1) // 2 if n % 2 else (n // 2 - 1, n // 2), axis=0)
    if n % 2:
        return part[n // 2].astype(np.float64)
    return (part[n // 2 - 1].astype(np.float64) + part[n // 2]) / 2.0
