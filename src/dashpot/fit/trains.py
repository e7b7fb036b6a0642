"""Predicted trains of a contact model for many parameter sets at once: impact times, speeds
and restitution, in the fit's units (s, m/s).
"""

from __future__ import annotations

import numpy as np

from ..physics.models import EXACT_RTOL
from ..physics.train import impact_trains


def _impact_times(trains, omega0):
    """Impact times in s from the first, one row per train (ω0 in rad/s per train); after a
    capture the ball rests on the surface, so later impacts keep the last time."""
    times = np.zeros(trains.speeds.shape)
    np.cumsum(trains.intervals, axis=1, out=times[:, 1:])
    return times / omega0[:, None]


class _TrainPredictor:
    """Predicted trains of one model for many parameter sets at once, each evaluation started
    from the previous one's train (Newton's start; see :func:`impact_trains`)."""

    def __init__(self, model, g, count, trains_solver=impact_trains):
        self.model, self.g, self.count = model, g, count
        self.trains_solver = trains_solver
        self.start = None
        self.error_bound = 0.0

    def __call__(self, zeta, omega0, v0):
        """Trains at arrays (or scalars) ζ, ω0 (rad/s), v0 (m/s), one row per parameter set.

        Returns
        -------
        trains : ImpactTrains
        times : ndarray, shape (sets, count)
            Impact times in s from the first; after a capture the ball rests on the surface,
            so later impacts keep the last time.
        speeds, rebound : ndarray, shape (sets, count)
            Impact and rebound speeds in m/s (0 after a capture).
        """
        zeta, omega0, v0 = (np.atleast_1d(np.asarray(value, float))
                            for value in (zeta, omega0, v0))
        if not zeta.shape == omega0.shape == v0.shape:
            zeta, omega0, v0 = np.broadcast_arrays(zeta, omega0, v0)
        v_star = self.g / omega0
        start = (None if self.start is None
                 else np.broadcast_to(self.start, (zeta.size, self.count)))
        trains = self.trains_solver(self.model, zeta, v0 / v_star, self.count, start=start,
                                    rtol=EXACT_RTOL)
        self.error_bound = max(self.error_bound, float(np.max(trains.error_bound)))
        first = int(trains.impacts[0])
        ratios = trains.speeds[0, :first] / trains.speeds[0, 0]
        if first < self.count:
            # Captured early: keep a usable start by continuing the last ratio geometrically.
            last = ratios[-1] * (ratios[-1] / ratios[-2] if first > 1 else 0.5) ** np.arange(
                1, self.count - first + 1)
            ratios = np.concatenate([ratios, np.maximum(last, 1e-300)])
        self.start = ratios
        times = _impact_times(trains, omega0)
        speeds = trains.speeds * v_star[:, None]
        return trains, times, speeds, trains.restitution * speeds


def _train_times(model, data, zeta, omega0, v0, start=None, trains_solver=impact_trains):
    """Predicted times (s, from the first impact) of the observed impacts, many trains at once.

    A train captured before the last observed impact rests at its last one.

    Returns
    -------
    times : ndarray, shape (trains, observed impacts)
    trains : ImpactTrains
    """
    trains = trains_solver(model, zeta, v0 * omega0 / data.g, data.count, start=start)
    return _impact_times(trains, omega0)[:, data.index], trains


def _restitution(trains_solver, model, zeta, vtilde):
    """ε and the capture flag at (ζ, ṽ) (broadcast) from trains of one impact: the surrogate
    levels' compiled pass costs a fraction of a ``collide`` call on the tables for the few
    hundred points of a fit."""
    zeta, vtilde = np.broadcast_arrays(zeta, vtilde)
    trains = trains_solver(model, zeta.ravel(), vtilde.ravel(), 1)
    return (trains.restitution[:, 0].reshape(zeta.shape),
            np.isinf(trains.contact_times[:, 0]).reshape(zeta.shape))
