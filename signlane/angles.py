"""Angles in radians."""
from __future__ import annotations

import math


def wrap_pi(a):
    """An angle (float or numpy array) brought into [-pi, pi): the short way round."""
    return (a + math.pi) % (2 * math.pi) - math.pi
