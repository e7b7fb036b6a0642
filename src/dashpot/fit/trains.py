"""Predicted trains of a contact model for many parameter sets at once: impact times, speeds
and restitution, in the fit's units (s, m/s).

The flight between impacts is gravity's unless the fit gives its flight parameters
(:data:`FLIGHT_PARAMETERS`, SI units): the drag constant k_d (1/m), the mean acceleration of
the flight g_eff (m/s²) and a friction deceleration f (m/s²), so that the body decelerates at
a_away = g_eff + f moving away from the surface and accelerates at a_toward = g_eff − f coming
back (rolling friction of a cart opposes the motion on both legs) [1]_. The contact stays under
the data's driving acceleration g (the unit of v* = g/ω0). With k_d = 0, g_eff = g and f = 0
the trains are today's gravity-only ones exactly.

References
----------
.. [1] :mod:`dashpot.physics.flight` (the track flight: two accelerations and quadratic drag).
"""

from __future__ import annotations

import numpy as np

from ..physics.models import EXACT_RTOL
from ..physics.train import TrackFlight, impact_trains

FLIGHT_PARAMETERS = ("k_d", "g_eff", "friction")
"""Fitted coordinates of the flight, after :data:`~dashpot.fit.settings.PARAMETERS`: drag
constant (1/m), mean flight acceleration (m/s²), friction deceleration (m/s²)."""


def _track_flight(g, v_star, k_d=None, g_eff=None, friction=None):
    """The dimensionless :class:`TrackFlight` of each train (None: gravity's).

    Parameters
    ----------
    g : float
        Driving acceleration of the contact in m/s² (the unit of the accelerations).
    v_star : ndarray
        g/ω0 of each train in m/s.
    k_d, g_eff, friction : float or ndarray, optional
        Flight parameters (SI); None: 0, g, 0.
    """
    if k_d is None and g_eff is None and friction is None:
        return None
    k_d = 0.0 if k_d is None else k_d
    g_eff = g if g_eff is None else g_eff
    friction = 0.0 if friction is None else friction
    if np.all(k_d == 0.0) and np.all(g_eff == g) and np.all(friction == 0.0):
        return None
    return TrackFlight.of((g_eff + friction) / g, (g_eff - friction) / g, k_d * v_star ** 2 / g,
                          np.size(v_star))


def _flight_accepted(k_d=0.0, g_eff=1.0, friction=0.0):
    """Mask of physical flight parameters: k_d >= 0 and both accelerations > 0."""
    return (np.asarray(k_d) >= 0.0) & (np.asarray(g_eff) - np.abs(friction) > 0.0)


def _impact_times(trains, omega0):
    """Impact times in s from the first, one row per train (ω0 in rad/s per train); after a
    capture the ball rests on the surface, so later impacts keep the last time."""
    times = np.zeros(trains.speeds.shape)
    np.cumsum(trains.intervals, axis=1, out=times[:, 1:])
    return times / omega0[:, None]


class _TrainPredictor:
    """Predicted trains of one model for many parameter sets at once, each evaluation started
    from the previous one's train (Newton's start; see :func:`impact_trains`)."""

    flight_parameters = FLIGHT_PARAMETERS

    def __init__(self, model, g, count, trains_solver=impact_trains):
        self.model, self.g, self.count = model, g, count
        self.trains_solver = trains_solver
        self.start = None
        self.error_bound = 0.0

    @staticmethod
    def accepts(*flight):
        """Mask of the parameter sets whose flight columns (:data:`FLIGHT_PARAMETERS`) are
        physical."""
        return _flight_accepted(*flight)

    def __call__(self, zeta, omega0, v0, *flight):
        """Trains at arrays (or scalars) ζ, ω0 (rad/s), v0 (m/s), one row per parameter set,
        and optionally the flight parameters k_d (1/m), g_eff (m/s²), friction (m/s²) (in the
        order of :data:`FLIGHT_PARAMETERS`; default gravity's flight).

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
        flight = _track_flight(self.g, v_star, *flight)
        options = {} if flight is None else {"flight": flight}
        trains = self.trains_solver(self.model, zeta, v0 / v_star, self.count, start=start,
                                    rtol=EXACT_RTOL, **options)
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


def _train_times(model, data, zeta, omega0, v0, start=None, trains_solver=impact_trains,
                 flight=()):
    """Predicted times (s, from the first impact) of the observed impacts, many trains at once.

    A train captured before the last observed impact rests at its last one. `flight` holds
    the flight parameters (:data:`FLIGHT_PARAMETERS`, SI; empty: gravity's flight).

    Returns
    -------
    times : ndarray, shape (trains, observed impacts)
    trains : ImpactTrains
    """
    track = _track_flight(data.g, data.g / np.asarray(omega0, float), *flight)
    options = {} if track is None else {"flight": track}
    trains = trains_solver(model, zeta, v0 * omega0 / data.g, data.count, start=start,
                           **options)
    return _impact_times(trains, omega0)[:, data.index], trains


def _restitution(trains_solver, model, zeta, vtilde):
    """ε and the capture flag at (ζ, ṽ) (broadcast) from trains of one impact: the surrogate
    levels' compiled pass costs a fraction of a ``collide`` call on the tables for the few
    hundred points of a fit."""
    zeta, vtilde = np.broadcast_arrays(zeta, vtilde)
    trains = trains_solver(model, zeta.ravel(), vtilde.ravel(), 1)
    return (trains.restitution[:, 0].reshape(zeta.shape),
            np.isinf(trains.contact_times[:, 0]).reshape(zeta.shape))
