"""Restitution laws with one speed term beside ε at v = 0: linear, quadratic and power.

==========  ==========================  ============
law         ε(v)                        parameters
==========  ==========================  ============
linear      e0 − α·v                    e0, α (s/m)
quadratic   e0 − c·v²                   e0, c (s²/m²)
power       a·v^(−b)  (v in m/s)        a, b
==========  ==========================  ============

Each adds a "speed term" to the constant law on the selection ladder. Where a formula leaves
[0, 1] (a linear law past v = e0/α, a power law below the speed where a·v^(−b) = 1) ε is
clipped by :meth:`dashpot.physics.laws.RestitutionLaw.__call__` and the point flagged.
"""

from __future__ import annotations

import numpy as np

from .base import RestitutionLaw, no_flag, parameter

__all__ = ["LAW_SPECS", "linear", "power", "quadratic"]


def linear(speed, e0, alpha):
    """ε = e0 − α·v (α in s/m)."""
    return e0 - alpha * speed, -alpha * speed, no_flag(speed.shape)


def quadratic(speed, e0, c):
    """ε = e0 − c·v² (c in s²/m²)."""
    term = c * speed * speed
    return e0 - term, -2.0 * term, no_flag(speed.shape)


def power(speed, a, b):
    """ε = a·v^(−b) with v in m/s (a is ε at 1 m/s), v·dε/dv = −b·ε.

    Evaluated in logarithms and capped at e > 1 before the exponential, so v → 0 gives no
    overflow: there ε is clipped to 1 (b > 0) or tends to 0 (b < 0).
    """
    tiny = np.finfo(float).tiny
    with np.errstate(divide="ignore"):
        log_eps = np.log(np.maximum(a, 0.0)) - b * np.log(np.maximum(speed, tiny))
    eps = np.exp(np.minimum(log_eps, 1.0))
    # A negative a gives no real power law: ε < 0 is clipped (and flagged) by the caller.
    eps = np.where(a < 0.0, -1.0, eps)
    return eps, -b * eps, no_flag(speed.shape)


_E0 = ("e0", "", 0.0, 1.0, 0.9, "restitution extrapolated to v = 0")


def _e0_start(eps, typical):
    return {"e0": eps}


LAW_SPECS = (
    RestitutionLaw(
        "linear", "ε = e0 − α·v",
        (parameter(*_E0), parameter("alpha", "s/m", -0.2, 0.2, 0.0,
                                    "fall of ε per unit impact speed")),
        linear, "—", start=_e0_start),
    RestitutionLaw(
        "quadratic", "ε = e0 − c·v²",
        (parameter(*_E0), parameter("c", "s²/m²", -0.1, 0.1, 0.0,
                                    "fall of ε per squared impact speed")),
        quadratic, "—", start=_e0_start),
    RestitutionLaw(
        "power", "ε = a·(v / 1 m/s)^(−b)",
        (parameter("a", "", 0.0, 1.5, 0.9, "ε at 1 m/s"),
         parameter("b", "", -0.3, 0.3, 0.0, "exponent of the fall of ε with speed")),
        power, "—", start=lambda eps, typical: {"a": eps}),
)
"""The laws this module defines, in ladder order (collected in
:data:`dashpot.physics.laws.LAWS`)."""
