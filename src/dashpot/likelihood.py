"""Likelihood of a train of impact times with bounce-to-bounce scatter and timing noise.

Real bounces do not follow one deterministic train: each rebound scatters by a few tenths of
a percent (spin, seams, contact point) and the scatter accumulates along the train. The train
is therefore a state-space model [1]_ over the state x_n = (t_n, u_n), the time and speed of
impact n:

==========  ===================================================  ==========================
step        equation                                             noise
==========  ===================================================  ==========================
bounce      v_n = R(u_n)·(1 + η_n)                               η_n ~ N(0, σ_ε²) (process)
flight      t_{n+1} = t_n + τ(u_n) + T(v_n),  u_{n+1} = L(v_n)   —
detection   y_n = t_n + e_n                                      e_n ~ N(0, s²σ_n² + σ_j²)
==========  ===================================================  ==========================

R is the deterministic restitution law (rebound speed against impact speed; ε(u) = R(u)/u),
τ the contact duration, T and L the flight duration and landing speed of
:mod:`dashpot.physics.flight`. The timing error of impact n has the detector's own 1σ
uncertainty σ_n multiplied by a scale s and a jitter σ_j added in quadrature: with s = 1 the
fitted σ_j is the timing noise the detector did not report (a one-sample uncertainty is 3-10×
too optimistic on real audio); with σ_n = 0 the jitter σ_j is the whole timing noise σ_t. Fit one
of s and σ_j (both at once are degenerate where the σ_n are all equal).

The likelihood is evaluated by an extended Kalman filter [2]_: the bounce and flight are
linearized about the current state estimate (the slopes dR/du, dτ/du, dT/dv, dL/dv come from
the law and flight functions), the measurement is linear. It returns −2 ln L, the innovations
y_n − E[t_n | y_0 … y_{n−1}] and their variances; the standardized innovations are N(0, 1)
and independent when the model is right, which is what a fit's residual checks test. With
σ_ε = 0 every state variance stays 0 and the likelihood is exactly that of the deterministic
train with independent timing errors (the fit of :mod:`dashpot.fit`). With σ_ε > 0 the error of
the linearization is second order in the state spread, about (σ_ε·T''/T')² relative, far below
the noise for the scatter of real balls (tenths of a percent).

The start speed u_0 is a parameter (variance 0). The start time t_0 is either a parameter too
(the first innovation is then y_0 − t_0) or, with ``start_time=None``, integrated out under a
flat prior: the first observed impact anchors the train and the likelihood is that of the times
relative to it (of the intervals). Fit the noise with t_0 integrated out: as a parameter, t_0 =
y_0 with σ_t → 0 makes −2 ln L unbounded below whenever σ_ε > 0. Missing impacts (NaN times)
are predicted through without an update.
Every array broadcasts over a leading batch of parameter sets (or of trains): the loop runs over
the impacts only, numpy over the batch, so the finite-difference stencils of a fit, or a
hundred simulated trials, cost about one evaluation.

The same filter runs faster over a table of the step map (:meth:`TrainModel.tabulate`): the
law, contact time and flight are evaluated once per call, for every parameter set at once, on
a grid of speeds, and :meth:`StepTable.filter` runs the loop, compiled by numba, over their
cubic Hermite interpolant; its arithmetic is that of :meth:`TrainModel.filter`, step for step,
and a parameter set whose speed leaves the grid is reported rather than extrapolated. This is
what the fits' fast and standard accuracy levels use (:mod:`dashpot.fit.noise_fit`).

References
----------
.. [1] J. Durbin and S. J. Koopman, *Time Series Analysis by State Space Methods*, 2nd ed.,
   Oxford University Press (2012), ch. 4 (Kalman filter, prediction-error decomposition of the
   likelihood) and §10.2 (extended Kalman filter).
.. [2] A. H. Jazwinski, *Stochastic Processes and Filtering Theory*, Academic Press (1970),
   ch. 8-9 (extended Kalman filter).
.. [3] S. Seabold and J. Perktold, statsmodels ``tsa.statespace`` (2010-): the model's
   specification kept apart from the filter, and every model able to simulate its own data.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numba
import numpy as np

from .physics.flight import Flight

__all__ = ["SimulatedTrain", "StepTable", "TrainFilter", "TrainModel"]

LOG_TWO_PI = math.log(2.0 * math.pi)


@dataclass(frozen=True)
class TrainFilter:
    """Output of the Kalman filter over one or many impact trains (batch first).

    The batch shape is that of the parameters and of the times' leading axes broadcast
    together: () for one train under one parameter set, then the arrays are 1-D.

    Attributes
    ----------
    neg2_log_likelihood : ndarray, shape (batch,)
        −2 ln L of the observed times (times in s): Σ_n [r_n²/S_n + ln(2π S_n)] over the
        observed impacts; inf where an innovation variance is 0 (no timing noise on an impact
        whose time the model predicts with certainty, such as the first).
    innovations : ndarray, shape (batch, impacts)
        r_n = y_n − (predicted t_n) in s; NaN where the time is missing.
    innovation_variance : ndarray, shape (batch, impacts)
        S_n, predicted variance of t_n plus the timing variance, in s².
    predicted_times : ndarray, shape (batch, impacts)
        One-step prediction E[t_n | y_0 … y_{n−1}] in s.
    predicted_speeds : ndarray, shape (batch, impacts)
        One-step prediction of the impact speed u_n in m/s.
    filtered_speeds : ndarray, shape (batch, impacts)
        E[u_n | y_0 … y_n] in m/s.
    scored : ndarray of bool, shape (batch, impacts)
        Where an innovation was scored: the observed impacts, less the first one when the
        start time is diffuse.
    """

    neg2_log_likelihood: np.ndarray
    innovations: np.ndarray
    innovation_variance: np.ndarray
    predicted_times: np.ndarray
    predicted_speeds: np.ndarray
    filtered_speeds: np.ndarray
    scored: np.ndarray

    @property
    def standardized(self):
        """r_n/√S_n: independent N(0, 1) under the model; NaN where missing, shape (batch, n)."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return self.innovations / np.sqrt(self.innovation_variance)

    @property
    def chi_square(self):
        """Σ_n r_n²/S_n over the scored impacts, shape (batch,)."""
        return np.sum(np.where(self.scored, self.standardized, 0.0) ** 2, axis=-1)


@dataclass(frozen=True)
class SimulatedTrain:
    """Impact trains drawn from a :class:`TrainModel` (batch first, SI units).

    Attributes
    ----------
    times : ndarray, shape (batch, impacts)
        Measured impact times y_n in s (true times plus timing noise).
    true_times : ndarray, shape (batch, impacts)
        t_n in s.
    impact_speeds : ndarray, shape (batch, impacts)
        u_n in m/s.
    rebound_speeds : ndarray, shape (batch, impacts)
        v_n = R(u_n)(1 + η_n) in m/s (clipped at 0: a draw η_n < −1, at 100σ_ε for real
        balls, would reverse the ball).
    """

    times: np.ndarray
    true_times: np.ndarray
    impact_speeds: np.ndarray
    rebound_speeds: np.ndarray


@dataclass(frozen=True)
class TrainModel:
    """A bounce train as a state-space model: restitution law, flight and contact duration.

    The callables take arrays of impact (or launch) speeds of shape (batch,) and carry their
    own parameters (closures over per-batch arrays), e.g.
    ``TrainModel(lambda u: (eps * u, eps), lambda v: drag_flight(v, g_eff, k_d))``.

    Attributes
    ----------
    rebound : callable
        ``rebound(u) -> (v, dv/du)``: deterministic rebound speed in m/s at impact speed u.
    flight : callable
        ``flight(v) -> Flight``: flight after a rebound at v
        (:func:`dashpot.physics.flight.drag_flight`, ``gravity_flight``, ``incline_flight``).
    contact_time : callable or None
        ``contact_time(u) -> (τ, dτ/du)`` in s and s²/m; None for instantaneous impacts.
    """

    rebound: Callable
    flight: Callable[[np.ndarray], Flight]
    contact_time: Callable | None = None

    def _step(self, speed):
        """(duration to the next impact, next impact speed, both slopes, noise gains) at u,
        and where the step is not finite (a parameter set whose train leaves the float range
        or is captured: its speeds are carried on at 0, so that it does not stop the batch)."""
        speed, broken = _finite_speed(speed)
        rebound, rebound_slope = self.rebound(speed)
        rebound, bad = _finite_speed(rebound)
        broken = broken | bad
        flight = self.flight(rebound)
        duration, duration_slope = flight.duration, flight.duration_slope * rebound_slope
        if self.contact_time is not None:
            contact, contact_slope = self.contact_time(speed)
            duration, duration_slope = duration + contact, duration_slope + contact_slope
        # A relative kick η to the rebound speed moves the next impact by T'(v)·v·η in time
        # and by L'(v)·v·η in speed.
        out = (duration, flight.landing_speed, duration_slope,
               flight.landing_slope * rebound_slope, flight.duration_slope * rebound,
               flight.landing_slope * rebound)
        for value in out:
            broken = broken | ~np.isfinite(value)
        return tuple(np.where(broken, 0.0, value) for value in out) + (broken,)

    def step(self, speed):
        """The linearized step from impact speed(s) `speed` (m/s) to the next impact.

        Returns
        -------
        duration, landing, duration_slope, landing_slope, timing_gain, speed_gain : ndarray
            Time to the next impact D(u) = τ(u) + T(R(u)) in s, the next impact speed L(R(u))
            in m/s, their slopes dD/du (s²/m) and d(L∘R)/du, and the shifts of the next
            impact's time (T'(v)·v, s) and speed (L'(v)·v, m/s) per unit relative kick η of
            the rebound speed v = R(u); all 0 where the step is not finite.
        broken : ndarray of bool
            Where it is not (a speed outside the float range, a captured ball).
        """
        return self._step(speed)

    def tabulate(self, low, high, log_step):
        """The step map of every parameter set tabulated on one grid of speeds, for
        :meth:`StepTable.filter`.

        Parameters
        ----------
        low, high : float
            Speeds in m/s (0 < low < high) the grid must cover.
        log_step : float
            Spacing of the nodes in ln u: nodes u_j = low·exp(j·log_step) up to the first at
            or above `high`.

        Returns
        -------
        StepTable
            Values and u-slopes at the nodes, members in the callables' batch order (the
            callables are called once, on speeds of shape (nodes, 1) broadcast against their
            parameters of shape (members,)).
        """
        if not (0.0 < low < high and log_step > 0.0):
            raise ValueError(f"need 0 < low < high and log_step > 0; got low={low!r}, "
                             f"high={high!r}, log_step={log_step!r}")
        count = int(math.ceil(math.log(high / low) / log_step - 1e-9)) + 1
        return self.tabulate_at(low * np.exp(log_step * np.arange(max(count, 2))))

    def tabulate_at(self, nodes):
        """The step map tabulated at given speeds, for :meth:`StepTable.filter`.

        Parameters
        ----------
        nodes : array_like, shape (nodes,)
            Speeds in m/s, positive and increasing (at least two); the filter finds its
            interval fastest where they are evenly spaced in ln u (:meth:`tabulate`).

        Returns
        -------
        StepTable
        """
        nodes = np.asarray(nodes, dtype=float)
        if nodes.ndim != 1 or nodes.size < 2 or not (nodes[0] > 0.0 and np.all(
                np.diff(nodes) > 0.0) and np.isfinite(nodes[-1])):
            raise ValueError("nodes must be at least two finite positive increasing speeds")
        out = self._step(nodes[:, None])
        shape = np.broadcast_shapes(*(np.shape(a) for a in out))
        columns = np.empty((7,) + shape)
        for k, value in enumerate(out):
            columns[k] = value
        members = shape[1]
        values = np.empty((members, nodes.size, 4))
        slopes = np.empty((members, nodes.size, 4))
        unusable = np.empty((members, nodes.size), np.bool_)
        _assemble_table(columns, nodes, values, slopes, unusable)
        log_low = math.log(nodes[0])
        return StepTable(log_low=log_low, log_step=(math.log(nodes[-1]) - log_low)
                         / (nodes.size - 1), nodes=nodes, values=values, slopes=slopes,
                         unusable=unusable)

    def filter(self, times, *, start_time, start_speed, process_sigma, jitter=0.0,
               detector_sigma=0.0, sigma_scale=1.0):
        """Run the extended Kalman filter: −2 ln L, innovations and their variances.

        Parameters
        ----------
        times : array_like, shape (impacts,) or (batch, impacts)
            Measured impact times y_n in s, in train order; NaN for an impact not detected.
        start_time : float or ndarray, shape (batch,), or None
            t_0, time of the first impact in s, or None to leave it free (a flat prior,
            integrated out): the likelihood is then that of the times relative to the first
            observed one. Use None whenever σ_ε > 0 is fitted: with t_0 a parameter, t_0 = y_0
            and σ_t → 0 make the density of the first impact, and −2 ln L, unbounded below.
        start_speed : float or ndarray, shape (batch,)
            u_0, speed of the first impact in m/s.
        process_sigma : float or ndarray, shape (batch,)
            σ_ε: relative 1σ scatter of each rebound speed (0.003 for 0.3 %).
        jitter : float or ndarray, shape (batch,)
            σ_j in s, added in quadrature to the scaled detector uncertainty.
        detector_sigma : float or array_like, shape (impacts,) or (batch, impacts)
            σ_n, the detector's 1σ uncertainty of each time in s.
        sigma_scale : float or ndarray, shape (batch,)
            s, multiplying the detector's uncertainties.

        Returns
        -------
        TrainFilter
        """
        times = np.atleast_1d(np.asarray(times, dtype=float))
        diffuse = start_time is None
        t, u, process, jitter, scale = (np.asarray(a, dtype=float) for a in np.broadcast_arrays(
            np.nan if diffuse else start_time, start_speed, process_sigma, jitter, sigma_scale))
        count = times.shape[-1]
        timing_variance = (scale[..., None] * np.asarray(detector_sigma, dtype=float)) ** 2 \
            + jitter[..., None] ** 2
        timing_variance = np.broadcast_to(timing_variance, timing_variance.shape[:-1] + (count,))
        observed = np.isfinite(times)
        anchored = np.logical_not(diffuse)
        p_tt = p_tu = p_uu = total = 0.0
        broken = np.zeros((), bool)  # parameter sets whose train left the finite numbers
        # Columns of the outputs; the batch shape is known only once the model's callables,
        # which carry their own parameter arrays, have broadcast against the state.
        out = {name: [] for name in ("innovations", "variance", "times", "speeds", "filtered",
                                     "scored")}
        for n in range(count):
            y, observation = times[..., n], observed[..., n]
            # A diffuse start time is set by the first observed impact, which scores nothing.
            anchor, seen = observation & ~anchored, observation & anchored
            anchored = anchored | observation
            variance = np.where(seen, p_tt + timing_variance[..., n], np.nan)
            innovation = np.where(seen, y - t, np.nan)
            for name, value in (("times", t), ("speeds", u), ("innovations", innovation),
                                ("variance", variance), ("scored", seen)):
                out[name].append(value)
            positive = seen & (variance > 0.0)
            safe = np.where(positive, variance, 1.0)
            r = np.where(seen, innovation, 0.0)
            # S = 0 (no timing noise and a certain state) makes the time a certainty, not a
            # density: counted as impossible, so no minimizer is drawn there.
            total += np.where(seen, np.where(positive, r * r / safe + np.log(safe) + LOG_TWO_PI,
                                             np.inf), 0.0)
            # Update with impact n. Written so that nothing cancels: P_tt·R/S, not P_tt − P_tt²/S.
            gain_t = np.where(seen & positive, p_tt / safe, 0.0)
            gain_u = np.where(seen & positive, p_tu / safe, 0.0)
            t, u = t + gain_t * r, u + gain_u * r
            keep = np.where(seen & positive, timing_variance[..., n] / safe, 1.0)
            p_uu = np.maximum(p_uu - gain_u * p_tu, 0.0)
            p_tt, p_tu = p_tt * keep, p_tu * keep
            # Anchoring a diffuse time: t = y with the timing variance, uncorrelated with u
            # (the limit of the update as the prior variance of t grows without bound).
            t = np.where(anchor, y, t)
            p_tt = np.where(anchor, timing_variance[..., n], p_tt)
            p_tu = np.where(anchor, 0.0, p_tu)
            out["filtered"].append(u)
            if n == count - 1:
                break
            # Predict impact n + 1, linearized about the estimate (speeds below 0 are no state
            # a ball can be in; an update that far off is clipped, and shows in the innovations).
            duration, landing, f_tu, f_uu, g_t, g_u, bad = self._step(np.maximum(u, 0.0))
            broken = broken | bad
            g_t, g_u = g_t * process, g_u * process
            p_tt, p_tu, p_uu = (p_tt + 2.0 * f_tu * p_tu + f_tu * f_tu * p_uu + g_t * g_t,
                                f_uu * (p_tu + f_tu * p_uu) + g_t * g_u,
                                f_uu * f_uu * p_uu + g_u * g_u)
            t, u = t + duration, landing
        batch = np.broadcast_shapes(*(np.shape(a) for column in out.values() for a in column))
        out = {name: np.stack(np.broadcast_arrays(*column, np.empty(batch))[:-1], axis=-1)
               for name, column in out.items()}
        # A set that broke has no likelihood (inf, never NaN); the other sets keep theirs.
        total = np.where(broken | np.isnan(total), np.inf, total)
        return TrainFilter(neg2_log_likelihood=np.broadcast_to(total, batch).copy(),
                           innovations=out["innovations"], innovation_variance=out["variance"],
                           predicted_times=out["times"], predicted_speeds=out["speeds"],
                           filtered_speeds=out["filtered"], scored=out["scored"])

    def simulate(self, count, rng, *, start_time, start_speed, process_sigma, jitter=0.0,
                 detector_sigma=0.0, sigma_scale=1.0):
        """Draw impact trains from the model, exactly (the bounce map is not linearized).

        Parameters
        ----------
        count : int
            Number of impacts per train.
        rng : numpy.random.Generator
            Source of the process and timing noise.
        start_time, start_speed, process_sigma, jitter, detector_sigma, sigma_scale
            As in :meth:`filter`; a batch shape (trains,) draws that many trains.

        Returns
        -------
        SimulatedTrain
        """
        t, u, process, jitter, scale = (np.asarray(a, dtype=float) for a in np.broadcast_arrays(
            start_time, start_speed, process_sigma, jitter, sigma_scale))
        # The batch: the start's shape, or that of the parameters the callables carry.
        batch = np.broadcast_shapes(t.shape, np.shape(self.rebound(u)[0]))
        t, u = np.broadcast_to(t, batch), np.broadcast_to(u, batch)
        out = {name: np.empty(batch + (count,)) for name in ("times", "speeds", "rebounds")}
        for n in range(count):
            out["times"][..., n], out["speeds"][..., n] = t, u
            rebound, _ = self.rebound(u)
            rebound = np.maximum(rebound * (1.0 + process * rng.standard_normal(batch)), 0.0)
            out["rebounds"][..., n] = rebound
            flight = self.flight(rebound)
            contact = 0.0 if self.contact_time is None else self.contact_time(u)[0]
            t, u = t + contact + flight.duration, flight.landing_speed
        timing_sigma = np.sqrt((scale[..., None] * np.asarray(detector_sigma, dtype=float)) ** 2
                               + jitter[..., None] ** 2)
        measured = out["times"] + timing_sigma * rng.standard_normal(batch + (count,))
        return SimulatedTrain(times=measured, true_times=out["times"],
                              impact_speeds=out["speeds"], rebound_speeds=out["rebounds"])


@dataclass(frozen=True)
class StepTable:
    """The step map of a batch of train models on a shared grid of speeds (SI units), from
    :meth:`TrainModel.tabulate`, and the Kalman filter over it in a compiled loop.

    Between two nodes the duration D(u) and the next impact speed L(u) are cubic Hermite
    interpolants in u of the model's values and slopes at the nodes [4]_, so their error is
    about Δu⁴·max|D⁗|/384 per interval: fourth order in the node spacing, and nothing for a
    map linear in u (a constant ε under gravity). The slopes dD/du and dL/du the filter needs
    are the interpolants' derivatives (third order); the noise gains, which enter the
    variances only, are interpolated the same way from difference slopes. The nodes are
    spaced evenly in ln u, so that the relative resolution is the same at every speed.

    A parameter set whose filtered speed leaves the grid, or enters an interval next to a
    node where the step is not finite (a captured ball), is not extrapolated: the filter
    reports it in ``off_grid`` with the speed it stopped at, and the caller evaluates that
    step directly and runs the row again with it patched in (``patches``), or evaluates the
    row directly (:meth:`TrainModel.filter`).

    Attributes
    ----------
    log_low, log_step : float
        ln of the first node's speed (m/s) and the (mean) spacing of the nodes in ln u.
    nodes : ndarray, shape (nodes,)
        Speeds of the nodes in m/s.
    values : ndarray, shape (members, nodes, 4)
        D (s), L (m/s), the timing gain T'(v)·v (s) and the speed gain L'(v)·v (m/s), as
        returned by :meth:`TrainModel.step`.
    slopes : ndarray, shape (members, nodes, 4)
        Their u-slopes (s²/m, 1, s²/m, 1).
    unusable : ndarray of bool, shape (members, nodes)
        Nodes where the step is not finite, and their neighbours.

    References
    ----------
    .. [4] F. N. Fritsch and R. E. Carlson, "Monotone piecewise cubic interpolation", SIAM J.
       Numer. Anal. 17, 238-246 (1980), §2 (the cubic Hermite form and its error).
    """

    log_low: float
    log_step: float
    nodes: np.ndarray
    values: np.ndarray
    slopes: np.ndarray
    unusable: np.ndarray

    def _check_members(self, members):
        if members.size and not (0 <= members.min() and members.max() < self.values.shape[0]):
            raise ValueError(f"member indices must be in [0, {self.values.shape[0]}); got "
                             f"{members.min()} to {members.max()}")

    def interpolate(self, speed, members=None):
        """The interpolated step at speeds `speed` (m/s) of members `members` (broadcast).

        Returns
        -------
        duration, landing, duration_slope, landing_slope, timing_gain, speed_gain : ndarray
            As :meth:`TrainModel.step`; NaN where the speed is off the grid or unusable.
        """
        members = np.zeros((), int) if members is None else members
        speed, members = np.broadcast_arrays(np.asarray(speed, float),
                                             np.asarray(members, np.intp))
        self._check_members(members)
        out = np.empty((6, speed.size))
        ok = np.empty(speed.size, np.bool_)
        _interpolate_many(np.ascontiguousarray(speed).ravel(),
                          np.ascontiguousarray(members).ravel(), self.log_low, self.log_step,
                          self.nodes, self.values, self.slopes, self.unusable, out, ok)
        return tuple(np.where(ok, value, np.nan).reshape(speed.shape) for value in out)

    def filter(self, times, *, start_time, start_speed, process_sigma, jitter=0.0,
               detector_sigma=0.0, sigma_scale=1.0, members=None, patches=None):
        """The extended Kalman filter of :meth:`TrainModel.filter` over the tabulated step map.

        Parameters
        ----------
        times, start_time, start_speed, process_sigma, jitter, detector_sigma, sigma_scale
            As in :meth:`TrainModel.filter`, with at most one batch axis.
        members : array_like of int, shape (batch,), optional
            Which tabulated member (parameter set of the step map) each batch row uses;
            default: row i uses member i.
        patches : tuple of ndarray, optional
            ``(speeds (batch, k), steps (batch, k, 6), counts (batch,))``: steps the table
            cannot give, as :meth:`TrainModel.step` returns them (duration, landing and
            their slopes, the two noise gains), used where a row's speed is exactly one of
            its first `counts` patch speeds: a row that stopped at a speed runs on with the
            step evaluated there directly (the loop is deterministic, so it reaches that very
            speed again).

        Returns
        -------
        result : TrainFilter
            As from :meth:`TrainModel.filter`; NaN in the rows off the grid.
        off_grid : ndarray of bool, shape (batch,)
            Rows whose filtered speed left the grid or met an unusable node: to be evaluated
            directly.
        stop_speed : ndarray, shape (batch,)
            Where an off-grid row stopped: the speed (m/s) whose step the table could not
            give (NaN elsewhere). Where the model's own step is not finite there (a captured
            ball), the direct filter would stop there too, with −2 ln L = inf.
        """
        times = np.atleast_1d(np.asarray(times, dtype=float))
        diffuse = start_time is None
        members = np.arange(self.values.shape[0]) if members is None else members
        t, u, process, jitter, scale, members = (
            np.asarray(a) for a in np.broadcast_arrays(
                np.nan if diffuse else start_time, start_speed, process_sigma, jitter,
                sigma_scale, members))
        if t.ndim > 1 or times.ndim > 2:
            raise ValueError("StepTable.filter takes at most one batch axis")
        count = times.shape[-1]
        timing_variance = (scale[..., None] * np.asarray(detector_sigma, dtype=float)) ** 2 \
            + jitter[..., None] ** 2
        batch = np.broadcast_shapes(t.shape, times.shape[:-1], timing_variance.shape[:-1])
        flat = (int(np.prod(batch)), count)
        times = np.array(np.broadcast_to(times, batch + (count,)).reshape(flat))
        timing_variance = np.array(np.broadcast_to(timing_variance,
                                                   batch + (count,)).reshape(flat))
        t, u, process = (np.array(np.broadcast_to(a, batch).reshape(-1), dtype=float)
                         for a in (t, u, process))
        members = np.array(np.broadcast_to(members, batch).reshape(-1), dtype=np.intp)
        self._check_members(members)
        out = np.empty((5,) + flat)
        scored = np.zeros(flat, np.bool_)
        total = np.empty(flat[0])
        off_grid = np.zeros(flat[0], np.bool_)
        stop_speed = np.full(flat[0], np.nan)
        if patches is None:
            patches = (np.zeros((flat[0], 0)), np.zeros((flat[0], 0, 6)),
                       np.zeros(flat[0], np.intp))
        patch_speed, patch_step, patch_count = (np.ascontiguousarray(a, dtype=d) for a, d in
                                                zip(patches, (float, float, np.intp)))
        _filter_table(times, timing_variance, t, diffuse, u, process, members, self.log_low,
                      self.log_step, self.nodes, self.values, self.slopes, self.unusable,
                      patch_speed, patch_step, patch_count, out, scored, total, off_grid,
                      stop_speed)
        out = out.reshape((5,) + batch + (count,))
        result = TrainFilter(neg2_log_likelihood=total.reshape(batch), innovations=out[0],
                             innovation_variance=out[1], predicted_times=out[2],
                             predicted_speeds=out[3], filtered_speeds=out[4],
                             scored=scored.reshape(batch + (count,)))
        return result, off_grid.reshape(batch), stop_speed.reshape(batch)


@numba.njit(cache=True, inline="always")
def _combine(b00, b10, b01, b11, values, slopes, member, left, right, column):
    """One column of the table at a point between nodes `left` and `right`: the Hermite
    basis weights (or their derivatives) times the values and slopes there."""
    return (b00 * values[member, left, column] + b10 * slopes[member, left, column]
            + b01 * values[member, right, column] + b11 * slopes[member, right, column])


@numba.njit(cache=True, inline="always")
def _step_at(speed, member, log_low, log_step, nodes, values, slopes, unusable, hint=-1):
    """(found, D, L, dD/du, dL/du, timing gain, speed gain, interval) from the table at
    `speed` (m/s), looked for first in interval `hint`;
    found is false off the grid or in an interval with an unusable node. Cubic Hermite
    interpolation in u between the two nodes around `speed` (the basis computed once for the
    four quantities)."""
    last = nodes.size - 1
    if not (speed >= nodes[0] and speed <= nodes[last]):  # also false for NaN
        return False, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -1
    if hint >= 0 and hint < last and nodes[hint] <= speed <= nodes[hint + 1]:
        j = hint  # the interval of the step before: a ball slows by a few % per bounce
    elif hint >= 1 and hint < last and nodes[hint - 1] <= speed <= nodes[hint]:
        j = hint - 1  # or the one below
    else:
        j = min(int((math.log(speed) - log_low) / log_step), last - 1)
        # The logarithm's rounding may put a speed next to a node one interval off.
        if speed < nodes[j] and j > 0:
            j -= 1
        elif speed > nodes[j + 1] and j + 1 < last:
            j += 1
        if not nodes[j] <= speed <= nodes[j + 1]:
            # Nodes not evenly spaced in ln u: bisection.
            lo, hi = 0, last
            while hi - lo > 1:
                middle = (lo + hi) // 2
                if nodes[middle] <= speed:
                    lo = middle
                else:
                    hi = middle
            j = lo
    if unusable[member, j] or unusable[member, j + 1]:
        return False, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -1
    left = nodes[j]
    width = nodes[j + 1] - left
    s = (speed - left) / width
    s2 = s * s
    s3 = s2 * s
    # Hermite basis: values at the left and right node, slopes (times the width) there.
    h00, h10 = 2.0 * s3 - 3.0 * s2 + 1.0, (s3 - 2.0 * s2 + s) * width
    h01, h11 = 3.0 * s2 - 2.0 * s3, (s3 - s2) * width
    # Their derivatives in u.
    d00, d10 = (6.0 * s2 - 6.0 * s) / width, 3.0 * s2 - 4.0 * s + 1.0
    d01, d11 = -d00, 3.0 * s2 - 2.0 * s
    k = j + 1
    duration = _combine(h00, h10, h01, h11, values, slopes, member, j, k, 0)
    landing = _combine(h00, h10, h01, h11, values, slopes, member, j, k, 1)
    timing_gain = _combine(h00, h10, h01, h11, values, slopes, member, j, k, 2)
    speed_gain = _combine(h00, h10, h01, h11, values, slopes, member, j, k, 3)
    duration_slope = _combine(d00, d10, d01, d11, values, slopes, member, j, k, 0)
    landing_slope = _combine(d00, d10, d01, d11, values, slopes, member, j, k, 1)
    return True, duration, landing, duration_slope, landing_slope, timing_gain, speed_gain, j


@numba.njit(cache=True)
def _assemble_table(columns, nodes, values, slopes, unusable):
    """Values, u-slopes and unusable nodes of a StepTable from the step's seven outputs
    `columns` (7, nodes, members) of :meth:`TrainModel.step`.

    The noise gains enter only the variances: their slopes are second-order finite
    differences on the (uneven) nodes [5]_, exact where the gains are quadratic in u; the
    values and slopes of D and L are the model's own. A node where the step is broken, or
    next to one (its difference slope is spoilt), is unusable.

    .. [5] B. Fornberg, "Generation of finite difference formulas on arbitrarily spaced
       grids", Math. Comp. 51, 699-706 (1988) (three-point weights).
    """
    count, members = columns.shape[1], columns.shape[2]
    for m in range(members):
        for i in range(count):
            values[m, i, 0], values[m, i, 1] = columns[0, i, m], columns[1, i, m]
            values[m, i, 2], values[m, i, 3] = columns[4, i, m], columns[5, i, m]
            slopes[m, i, 0], slopes[m, i, 1] = columns[2, i, m], columns[3, i, m]
            # Three nodes around i (the two first or last at the ends) and their weights.
            c = min(max(i, 1), count - 2)
            a, b = nodes[c] - nodes[c - 1], nodes[c + 1] - nodes[c]
            x = nodes[i] - nodes[c]
            w0 = (2.0 * x - b) / (a * (a + b))
            w1 = -(2.0 * x + a - b) / (a * b)
            w2 = (2.0 * x + a) / (b * (a + b))
            for q in (2, 3):
                slopes[m, i, q] = (w0 * columns[q + 2, c - 1, m] + w1 * columns[q + 2, c, m]
                                   + w2 * columns[q + 2, c + 1, m])
        for i in range(count):
            bad = columns[6, i, m] != 0.0
            if i > 0 and columns[6, i - 1, m] != 0.0:
                bad = True
            if i + 1 < count and columns[6, i + 1, m] != 0.0:
                bad = True
            for q in range(4):
                if not (math.isfinite(values[m, i, q]) and math.isfinite(slopes[m, i, q])):
                    bad = True
            unusable[m, i] = bad
            if bad:
                for q in range(4):
                    values[m, i, q] = 0.0
                    slopes[m, i, q] = 0.0


@numba.njit(cache=True)
def _interpolate_many(speed, members, log_low, log_step, nodes, values, slopes, unusable, out,
                      ok):
    for i in range(speed.size):
        found, d, l, fd, fl, gt, gu, _ = _step_at(speed[i], members[i], log_low, log_step,
                                                  nodes, values, slopes, unusable)
        ok[i] = found
        out[0, i], out[1, i], out[2, i], out[3, i], out[4, i], out[5, i] = d, l, fd, fl, gt, gu


@numba.njit(cache=True, inline="always")
def _observe(x, p_xx, p_xo, p_oo, o, measured, noise):
    """Scalar update of a state (x, o) with a measurement of x (an impact time or a speed) of
    variance `noise`: (x, P_xx, P_xo, P_oo, o, innovation, its variance, −2 ln L term; inf
    with the state unchanged where the innovation has no variance). Written so that nothing
    cancels in the measured component's variance (P_xx·R/S); the other's is clipped at 0.
    For the impact time it is the arithmetic of :meth:`TrainModel.filter`."""
    variance = p_xx + noise
    r = measured - x
    if not variance > 0.0:
        return x, p_xx, p_xo, p_oo, o, r, variance, math.inf
    term = r * r / variance + math.log(variance) + LOG_TWO_PI
    gain_x, gain_o = p_xx / variance, p_xo / variance
    keep = noise / variance
    p_oo = max(p_oo - gain_o * p_xo, 0.0)
    return x + gain_x * r, p_xx * keep, p_xo * keep, p_oo, o + gain_o * r, r, variance, term


@numba.njit(cache=True)
def _observe_time(y, timing, anchored, t, u, p_tt, p_tu, p_uu):
    """An impact time y (variance `timing`) taken into the state (t, u) with covariance
    (p_tt, p_tu, p_uu): scored by :func:`_observe` once an earlier time has anchored the
    diffuse start, else, at the first observed time, the start anchored there.

    Returns (seen, anchored, innovation, its variance, −2 ln L term, t, u, p_tt, p_tu, p_uu):
    innovation and variance NaN and the term 0 where the time is not scored.
    """
    observation = math.isfinite(y)
    seen = observation and anchored
    innovation = variance = math.nan
    term = 0.0
    if seen:
        # No timing noise on a certain prediction (no variance) is impossible: inf.
        t, p_tt, p_tu, p_uu, u, innovation, variance, term = _observe(
            t, p_tt, p_tu, p_uu, u, y, timing)
    elif observation:
        t, p_tt, p_tu = y, timing, 0.0
    return seen, anchored or observation, innovation, variance, term, t, u, p_tt, p_tu, p_uu


@numba.njit(cache=True)
def _filter_table(times, timing_variance, start_time, diffuse, start_speed, process, members,
                  log_low, log_step, nodes, values, slopes, unusable, patch_speed,
                  patch_step, patch_count, out, scored, total, off_grid, stop_speed):
    """The loop of :meth:`TrainModel.filter`, row by row, over the tabulated step map.

    out[0..4] receive the innovations, their variances, the predicted times and speeds and the
    filtered speeds; the arithmetic is that of the numpy loop, step for step.
    """
    rows, count = times.shape
    for b in range(rows):
        t, u = start_time[b], start_speed[b]
        member = members[b]
        anchored = not diffuse
        p_tt = p_tu = p_uu = 0.0
        value = 0.0
        broken = False
        interval = -1
        for n in range(count):
            out[2, b, n], out[3, b, n] = t, u
            (scored[b, n], anchored, out[0, b, n], out[1, b, n], term,
             t, u, p_tt, p_tu, p_uu) = _observe_time(times[b, n], timing_variance[b, n],
                                                     anchored, t, u, p_tt, p_tu, p_uu)
            value += term
            out[4, b, n] = u
            if n == count - 1:
                break
            found, duration, landing, f_tu, f_uu, g_t, g_u, interval = _step_at(
                max(u, 0.0), member, log_low, log_step, nodes, values, slopes, unusable,
                interval)
            if not found:
                speed = max(u, 0.0)
                for k in range(patch_count[b]):
                    if patch_speed[b, k] == speed:
                        found = True
                        duration, landing = patch_step[b, k, 0], patch_step[b, k, 1]
                        f_tu, f_uu = patch_step[b, k, 2], patch_step[b, k, 3]
                        g_t, g_u = patch_step[b, k, 4], patch_step[b, k, 5]
                        break
            if not found:
                off_grid[b] = True
                stop_speed[b] = max(u, 0.0)
                break
            g_t, g_u = g_t * process[b], g_u * process[b]
            p_tt, p_tu, p_uu = (p_tt + 2.0 * f_tu * p_tu + f_tu * f_tu * p_uu + g_t * g_t,
                                f_uu * (p_tu + f_tu * p_uu) + g_t * g_u,
                                f_uu * f_uu * p_uu + g_u * g_u)
            t, u = t + duration, landing
            if not (math.isfinite(t) and math.isfinite(u)):
                broken = True
        if off_grid[b]:
            total[b] = math.nan
            for n in range(count):
                for q in range(5):
                    out[q, b, n] = math.nan
        else:
            total[b] = math.inf if broken or math.isnan(value) else value


def _finite_speed(speed):
    """(speed with non-finite values put at 0, where they were): a speed outside the float
    range is no state of a ball, and the flight and contact functions refuse it."""
    speed = np.asarray(speed, dtype=float)
    bad = ~np.isfinite(speed)
    return np.where(bad, 0.0, speed), bad
