"""The constant restitution law ε = e: the base of the ladder, every other law extends it."""

from __future__ import annotations

import numpy as np

from .base import RestitutionLaw, no_flag, parameter

__all__ = ["LAW_SPECS", "constant"]


def constant(speed, e):
    """ε = e at every speed."""
    return e.copy(), np.zeros(speed.shape), no_flag(speed.shape)


LAW_SPECS = (
    RestitutionLaw(
        "constant", "ε = e", (parameter("e", "", 0.0, 1.0, 0.9, "coefficient of restitution"),),
        constant, "—", start=lambda eps, typical: {"e": eps}, effect="", simpler=None),
)
"""The law this module defines (collected in :data:`dashpot.physics.laws.LAWS`)."""
