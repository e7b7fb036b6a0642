"""Predicted trains of a contact model for many parameter sets at once: impact times, speeds
and restitution, in the fit's units (s, m/s).

The flight between impacts is gravity's unless the fit carries flight effects of the registry
:data:`dashpot.physics.effects.FLIGHT_EFFECTS` (air drag, rolling friction, ...): their
parameters are the fit's flight columns (SI units, in the registry's order), and each effect
enters the coefficients of the track flight law (:class:`~dashpot.physics.effects.Track`:
deceleration a_up = gravity + away moving away from the surface, acceleration a_down =
gravity − toward coming back, quadratic drag k_d) [1]_; the train solvers fly that law in
units of the contact's g. The contact stays under the data's driving acceleration g (the unit
of v* = g/ω0). At a track that is gravity's exactly the trains are the gravity-only ones.

References
----------
.. [1] :mod:`dashpot.physics.flight` (the track flight: two accelerations and quadratic drag).
"""

from __future__ import annotations

import numpy as np

from ..physics.effects import FLIGHT_EFFECTS, flight_track
from ..physics.models import EXACT_RTOL
from ..physics.train import TrackFlight, impact_trains


def _flight_columns(effects):
    """Names of the flight columns of a fit carrying `effects`, in order."""
    return tuple(name for effect in effects for name in effect.parameter_names)


def _fit_track(effects, g, flight):
    """The :class:`~dashpot.physics.effects.Track` (m/s², 1/m) of the flight columns `flight`
    (in the order of :func:`_flight_columns`; floats or one array per column), or None
    where the fit carries no effect or no columns are given (gravity's flight)."""
    if not effects or len(flight) == 0:
        return None
    return flight_track(effects, g, dict(zip(_flight_columns(effects), flight)))


def _track_flight(g, v_star, track):
    """The dimensionless :class:`TrackFlight` of each train (None: gravity's).

    Parameters
    ----------
    g : float
        Driving acceleration of the contact in m/s² (the unit of the accelerations).
    v_star : ndarray
        g/ω0 of each train in m/s.
    track : Track or None
        The flight's coefficients (SI), floats or one value per train; None: gravity's.
    """
    if track is None:
        return None
    up, down, drag = track.up, track.down, track.drag
    if np.all(up == g) and np.all(down == g) and np.all(drag == 0.0):
        return None
    return TrackFlight.of(up / g, down / g, drag * v_star ** 2 / g, np.size(v_star))


def _track_accepted(track):
    """Mask of physical flights: drag k_d >= 0 and both accelerations a_up, a_down > 0 (True
    for gravity's flight, None)."""
    if track is None:
        return np.True_
    return ((np.asarray(track.drag) >= 0.0) & (np.asarray(track.up) > 0.0)
            & (np.asarray(track.down) > 0.0))


def _impact_times(trains, omega0):
    """Impact times in s from the first, one row per train (ω0 in rad/s per train); after a
    capture the ball rests on the surface, so later impacts keep the last time."""
    times = np.zeros(trains.speeds.shape)
    np.cumsum(trains.intervals, axis=1, out=times[:, 1:])
    return times / omega0[:, None]


class _TrainPredictor:
    """Predicted trains of one model for many parameter sets at once, each evaluation started
    from the previous one's train (Newton's start; see :func:`impact_trains`).

    `effects` are the flight effects the fit carries (registry entries, in the registry's
    order; default every registered one): the trains' flight columns are their parameters
    (``flight_parameters``)."""

    def __init__(self, model, g, count, trains_solver=impact_trains, effects=None):
        self.model, self.g, self.count = model, g, count
        self.trains_solver = trains_solver
        self.effects = tuple(FLIGHT_EFFECTS.values() if effects is None else effects)
        self.flight_parameters = _flight_columns(self.effects)
        self.start = None
        self.error_bound = 0.0

    def track(self, *flight):
        """The :class:`~dashpot.physics.effects.Track` of the flight columns (None: gravity's
        flight, the fit carries no effect)."""
        return _fit_track(self.effects, self.g, flight)

    def accepts(self, *flight):
        """Mask of the parameter sets whose flight columns give a physical flight (see
        :func:`_track_accepted`)."""
        return _track_accepted(self.track(*flight))

    def __call__(self, zeta, omega0, v0, *flight):
        """Trains at arrays (or scalars) ζ, ω0 (rad/s), v0 (m/s), one row per parameter set,
        and the flight columns (``flight_parameters``, SI; none given: gravity's flight).

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
        flight = _track_flight(self.g, v_star, self.track(*flight))
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
                 flight=None):
    """Predicted times (s, from the first impact) of the observed impacts, many trains at once.

    A train captured before the last observed impact rests at its last one. `flight` is the
    flight's :class:`~dashpot.physics.effects.Track` (SI; None: gravity's flight).

    Returns
    -------
    times : ndarray, shape (trains, observed impacts)
    trains : ImpactTrains
    """
    track = _track_flight(data.g, data.g / np.asarray(omega0, float), flight)
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
