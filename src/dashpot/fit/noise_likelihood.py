"""The likelihood of a noise fit (:mod:`dashpot.fit.noise_fit`): a law's parameters, the flight's
and the noise's laid out in rows, and −2 ln L of many rows at once.

The likelihood is that of :class:`dashpot.likelihood.TrainModel` (an extended Kalman filter over
impact time and speed, the start time integrated out), with the law's rebound (and, for a law
with a contact duration, its contact time) from the registry :data:`dashpot.physics.laws.LAWS`
and the flight's effects (:func:`dashpot.physics.flight.track_flight`) as columns of the step
map. The law enters only through its spec: its parameters and bounds, ``rebound``, and the
hooks ``contact``, ``scene_prior``, ``start`` and ``contact_model``.

Accuracy. The filter needs, at every impact of every parameter set, the step to the next
impact: duration D(u) = τ(u) + T(R(u)), next impact speed L(R(u)) and their slopes. At the
"exact" level these are evaluated directly, impact by impact (a numpy loop over the impacts,
one collision per step for a dashpot model). At "fast" and "standard" the step map of each
distinct set of law parameters in a batch is tabulated once per likelihood call on a grid of
speeds (GRID_BELOW to GRID_ABOVE times the speeds the intervals imply, 8 or 32 nodes per
e-fold, :meth:`dashpot.likelihood.TrainModel.tabulate`; the dashpot models' collisions from
the certified surrogate tables of that level) and the filter runs over its cubic Hermite
interpolant in a compiled loop (:class:`dashpot.likelihood.StepTable`); a step the table
cannot give (off the grid, or next to a speed where the ball is captured) is evaluated directly
and patched in. Measured by benchmarks/bench_noise.py (every
law on a 50-impact synthetic train and on the ping-pong recording), the fast level's step
map is within 5e-7 (relative) of the direct one, its −2 ln L within 3e-4 and its fitted
parameters within 5e-4 standard errors of the exact level's; the standard level's within
2e-9, 2e-6 and 1e-5 to 1e-3 (varying from run to run: there the optimizer's own convergence
dominates). "auto" fits at fast and
checks at the best fit: where −2 ln L is more than LEVEL_LIKELIHOOD_TOLERANCE = 0.01 from the
direct evaluation's, or a predicted time more than LEVEL_TIMING_TOLERANCE = 1 % of the
smallest timing σ, it fits again at the next level (as the deterministic fits' "auto" takes
the cheapest level that meets what the timing noise needs). A smooth error δ in −2 ln L moves
the best fit by about δ's slope over the curvature: a δ of 0.01 varying on the scale of a
standard error moves the parameters by about 0.01 of one. The result records the level
(``accuracy``), the measured relative error of the step map on the train's speeds at the best
fit (``error_bound``, 0 at "exact"; ``numerical_tolerance`` is that times the number of
impacts, as in the deterministic fits), and the differences to the direct evaluation in the
notes; the innovations, predictions and residuals reported are the direct filter's at the
best fit.

Measured speeds. Where the impact table carries a motion sensor's impact and rebound speeds
with their 1σ (``impact_speed``, ``rebound_speed``, ``speed_uncertainty`` of
:func:`dashpot.fit.prepare_data`), they are observations of the filter's state beside the
times (:func:`_speed_filter`): the step is split at the bounce, so that the rebound speed v_n
observes the state after the bounce and the impact speed u_{n+1} the state after the flight.
From the times alone friction (or drag) is degenerate with ε and v0, both making the
intervals geometric; v_n and u_{n+1}, measured on either side of one flight, differ by the
flight's loss alone. Each speed is taken at its stated σ and independent of the times and
of the other speeds, unless the table states their correlated errors (a motion reader's
speeds share the run's fitted leg accelerations and bumper position, and a flight's two
speeds its parabola: :class:`dashpot.fit.results.SpeedErrors`): then the shared errors and
each flight's own are states of the filter (:func:`_correlated_speed_filter`, exact for a
linear Gaussian train). A motion reader's impact times and speeds also come from fits of the
same samples and are in fact correlated; the table does not carry that. Such a filter
evaluates the law and flight at every step (a dashpot model's collisions from the surrogate
tables of the level) in a compiled loop per step: no step map is tabulated, and a scene
without speeds takes the times-only filter above, unchanged.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

from ..likelihood import (LOG_TWO_PI, TrainFilter, TrainModel, _finite_speed, _observe,
                          _observe_time)
from ..physics.effects import FLIGHT_EFFECTS, flight_map, flight_track
from ..physics.laws import LAWS
from .accuracy import _trains_solver
from .noise_settings import (
    FILTER_FIELDS,
    GRID_ABOVE,
    GRID_BELOW,
    GRID_LOG_STEPS,
    NOISE_PARAMETERS,
    PATCHES,
    SIGMA_EPS_FLOOR,
    SIGMA_J_FLOOR,
)
from .start import _flight_ratio_start, _start_values

__all__ = ["NoiseProblem"]



def _largest_relative_error(pairs):
    """Largest finite |approx − exact|/|exact| over (approx, exact) array pairs (0 if none)."""
    relative = 0.0
    for approx, exact in pairs:
        with np.errstate(invalid="ignore", divide="ignore"):
            error = np.abs(approx - exact) / np.abs(exact)
        relative = max(relative, float(np.max(error[np.isfinite(error)], initial=0.0)))
    return relative


def _filter_differences(tabulated, direct):
    """|Δ(−2 ln L)| and the largest |Δt| of predicted impact times between two filter runs
    of one parameter row (the tabulated step map against the direct evaluation)."""
    likelihood = abs(float(tabulated.neg2_log_likelihood[0])
                     - float(direct.neg2_log_likelihood[0]))
    timing = float(np.nanmax(np.abs(tabulated.predicted_times[0]
                                    - direct.predicted_times[0]), initial=0.0))
    return likelihood, timing


class NoiseProblem:
    """One law fitted to a batch of trains under the noise model: the parameter layout (the
    law's parameters, the flight's, v0, ln σ_ε, ln σ_j), the objective −2 ln L with priors, at
    the problem's accuracy level, and the start values. The fit itself is
    :class:`dashpot.fit.noise_fit._Problem`."""

    def __init__(self, datasets, law, scene, fixed, level="exact", effects=()):
        self.datasets, self.law_name, self.law = datasets, law, LAWS[law]
        self.model_name = law + "".join(f"+{effect}" for effect in effects)
        self.level = level
        self.accurate = {}  # train -> whether the level met its tolerances at the best fit
        self.g = float(datasets[0].g)
        if any(d.g != self.g for d in datasets):
            raise ValueError("every data set of one batch must have the same g")
        self.notes = []
        flight_bounds = self._flight_setup(scene, effects)
        self.names = self.law.parameter_names + tuple(self.flight_start) + NOISE_PARAMETERS
        # Columns of the law's and the flight's parameters: the step map's own (with v0 they
        # are the "mean" parameters).
        self.law_count = len(self.law.parameters) + len(self.flight_start)
        unknown = set(fixed) - set(self.names)
        if unknown:
            raise ValueError(f"cannot fix {sorted(unknown)[0]!r}: the parameters of law "
                             f"{law!r} are {', '.join(self.names)}")
        self.fixed, self.priors = self._known(scene, fixed)
        self.priors += [p for p in self.flight_priors if p[0] not in fixed]
        count = max(d.count for d in datasets)
        # Times on the train's grid: NaN where an impact was missed (or the train is shorter).
        self.times = np.full((len(datasets), count), np.nan)
        self.detector = np.zeros((len(datasets), count))
        for row, d in enumerate(datasets):
            self.times[row, d.index] = d.times
            # Without stated uncertainties the jitter is the whole timing noise.
            self.detector[row, d.index] = d.sigma if d.sigma_known else 0.0
        # Measured impact and rebound speeds (a motion sensor's), on the same grid, with their
        # variances: observations of the filter's state where a train has them
        # (:func:`_speed_filter`); without any the filter sees the times alone.
        self.impact_speed = np.full((len(datasets), count), np.nan)
        self.rebound_speed = np.full((len(datasets), count), np.nan)
        self.speed_variance = np.full((len(datasets), count), np.nan)
        for row, d in enumerate(datasets):
            self.impact_speed[row, d.index] = d.impact_speed
            self.rebound_speed[row, d.index] = d.rebound_speed
            self.speed_variance[row, d.index] = np.asarray(d.speed_sigma, float) ** 2
        measured = np.isfinite(self.speed_variance) & (self.speed_variance > 0.0)
        self.impact_speed[~measured] = np.nan
        self.rebound_speed[~measured] = np.nan
        self.has_speeds = bool(np.any(np.isfinite(self.impact_speed))
                               or np.any(np.isfinite(self.rebound_speed)))
        self.speed_errors = (self._speed_errors(datasets, count) if self.has_speeds and any(
            d.speed_errors is not None for d in datasets) else None)
        if self.speed_errors is not None:
            self.notes.append(
                "measured impact and rebound speeds used as observations of the filter's "
                "state, with the errors the table states them to share within the run (the "
                "shared errors and each flight's own as states of the filter; taken as "
                "independent of the times)")
        elif self.has_speeds:
            self.notes.append(
                "measured impact and rebound speeds used as observations of the filter's "
                "state, each with its stated sigma (taken as independent of the times and of "
                "each other)")
        # The step map depends on every parameter but v0 and the noise: the rows of a batch
        # that share these share one tabulated step map.
        self.step_columns = [i for i, n in enumerate(self.names) if n not in NOISE_PARAMETERS]
        implied = np.concatenate([0.5 * self.g * np.diff(d.times) / np.diff(d.index)
                                  for d in datasets])
        implied = implied[np.isfinite(implied) & (implied > 0.0)]
        if implied.size == 0:
            implied = np.array([1.0])
        self.grid = (GRID_BELOW * float(np.min(implied)), GRID_ABOVE * float(np.max(implied)))
        bounds = [(p.lower, p.upper) for p in self.law.parameters] + flight_bounds
        # v0 > 0; ln σ floored (see SIGMA_*_FLOOR), capped at 50 % scatter and 1 s.
        bounds += [(0.0, math.inf), (math.log(SIGMA_EPS_FLOOR), math.log(0.5)),
                   (math.log(SIGMA_J_FLOOR), 0.0)]
        self.lower, self.upper = (np.array(b, float) for b in zip(*bounds))
        # Columns whose bounds limit the steps only (the objective is defined beyond them).
        self.soft = (self.index("sigma_eps"), self.index("sigma_j"))
        # Steps and starts keep a margin inside the law's and v0's bounds, so that the
        # difference stencil around them is inside too: 1e-3 of a positive lower bound (v* of
        # the dashpot models, on a log-like scale), else 1e-9 of the span.
        span = np.where(np.isfinite(self.upper - self.lower), self.upper - self.lower, 0.0)
        margin = np.where(self.lower > 0.0, 1e-3 * self.lower, 1e-9 * span)
        soft = np.isin(np.arange(len(self.names)), self.soft)
        self.step_lower = np.where(soft, self.lower, self.lower + margin)
        self.step_upper = np.where(soft, self.upper, self.upper - 1e-9 * span)

    def _speed_errors(self, datasets, count):
        """The arguments `errors` of :func:`_correlated_speed_filter` on the trains' grid.

        A train without stated correlations has no shared component and its speeds' own
        variances are their σ². A flight's own error (SpeedErrors.flight_correlation ρ,
        own σ s_out of the rebound speed before it and s_in of the impact speed after it)
        enters both as √|ρ|·s·w, the rest independent: their covariance is ρ·s_out·s_in. Only
        between impacts next to each other on the grid (no missed impact between).
        """
        rank = max(d.speed_errors.shared_in.shape[1] for d in datasets
                   if d.speed_errors is not None)
        trains = len(datasets)
        shared_in, shared_out = (np.zeros((trains, count, rank)) for _ in range(2))
        flight_in, flight_out = (np.zeros((trains, count)) for _ in range(2))
        in_variance, out_variance = self.speed_variance.copy(), self.speed_variance.copy()
        for row, d in enumerate(datasets):
            errors = d.speed_errors
            if errors is None:
                continue
            index = d.index
            width = errors.shared_in.shape[1]
            shared_in[row, index, :width] = errors.shared_in
            shared_out[row, index, :width] = errors.shared_out
            rho = np.where(np.append(np.diff(index) == 1, False), errors.flight_correlation, 0.0)
            root = np.sqrt(np.abs(rho))
            after = errors.own_out * root
            before = np.concatenate([[0.0], np.sign(rho[:-1]) * errors.own_in[1:] * root[:-1]])
            flight_out[row, index], flight_in[row, index] = after, before
            measured = np.isfinite(self.speed_variance[row, index])
            in_variance[row, index] = np.where(measured, errors.own_in ** 2 - before ** 2, np.nan)
            out_variance[row, index] = np.where(measured, errors.own_out ** 2 - after ** 2,
                                                np.nan)
        return shared_in, shared_out, flight_in, flight_out, in_variance, out_variance

    # --- layout ---------------------------------------------------------------------------

    def _flight_setup(self, scene, effects):
        """The flight's fitted parameters: start values (``flight_start``, in column order),
        priors (``flight_priors``) and fixed values (``flight_fixed``); returns their bounds.

        Each effect of the registry :data:`dashpot.physics.effects.FLIGHT_EFFECTS` that the
        scene puts in every fit (drag where it gives the ball's mass and diameter) or that
        `effects` asks for sets its columns up from the scene (its ``setup``: start, bounds, a
        prior or a fixed value, and a note), in the registry's order (``flight_effects``).
        Without any, the flight is gravity's at g."""
        self.flight_start, self.flight_priors, self.flight_fixed = {}, [], {}
        self.flight_effects = []
        bounds = []
        for effect in FLIGHT_EFFECTS.values():
            setup = effect.columns(scene, self.g, effect.name in effects)
            if setup is None:
                continue
            self.flight_effects.append(effect)
            for column in setup.columns:
                self.flight_start[column.name] = column.start
                bounds.append((column.lower, column.upper))
                if column.fixed:
                    self.flight_fixed[column.name] = column.start
                elif column.prior is not None:
                    self.flight_priors.append((column.name, column.start, column.prior))
            self.notes.append(setup.note)
        return bounds

    def flight_of(self, rows):
        """``flight(v) -> Flight`` at the flight parameters of rows (sets, P) (the columns
        of the step map, or whole rows: the flight's come right after the law's), the
        registry's flight map of the fit's effects
        (:func:`dashpot.physics.effects.flight_map`)."""
        start = len(self.law.parameters)
        return flight_map(self.flight_effects, self.g,
                          {name: rows[:, start + k] for k, name in enumerate(self.flight_start)})

    def flight(self, v):
        """The flight at the start values of the flight parameters (for start values)."""
        row = np.array([[*([0.0] * len(self.law.parameters)), *self.flight_start.values()]])
        return self.flight_of(row)(v)

    def _known(self, scene, fixed):
        """Fixed values and Gaussian priors (name, centre, sd) from `fixed` and the scene."""
        values, priors = {}, []
        known_v0 = scene.known_impact_speed
        if known_v0 is not None and "v0" not in fixed:
            if known_v0.uncertainty is None:
                values["v0"] = known_v0.value
                self.notes.append("first impact speed known: v0 fixed")
            else:
                priors.append(("v0", known_v0.value, known_v0.uncertainty))
                self.notes.append("prior on v0 from the scene's first impact speed"
                                  if scene.first_impact_speed is not None else
                                  "prior on v0 = sqrt(2 g_eff h) from the scene's drop height")
        # The law's own parameter the scene knows (v* of a dashpot model from a known
        # stiffness and mass): fixed, or a Gaussian prior.
        known = (None if self.law.scene_prior is None
                 else self.law.scene_prior(scene.stiffness, scene.mass, self.g))
        if known is not None and known[0] not in fixed:
            name, value, sd, note = known
            if sd is None:
                values[name] = value
            else:
                priors.append((name, value, sd))
            self.notes.append(note)
        for name, value in self.flight_fixed.items():
            if name not in fixed:
                values[name] = value
        for name, value in fixed.items():
            value = float(value)
            if name in ("sigma_eps", "sigma_j"):
                if not value >= 0.0:
                    raise ValueError(f"{name} must be >= 0; got {value!r}")
                value = math.log(value) if value > 0.0 else -math.inf
            values[name] = value
        return values, priors

    def index(self, name):
        return self.names.index(name)

    def free(self, *also_fixed):
        return [i for i, name in enumerate(self.names)
                if name not in self.fixed and name not in also_fixed]

    # --- the objective ----------------------------------------------------------------------

    def model(self, rows, broken, level="exact"):
        """TrainModel of parameter rows (sets, P). Rows whose filter reaches a non-finite
        speed (a train captured by a dashpot model: infinite contact time) are marked in
        `broken` and carried on at speed 0, so one such row does not stop the batch. A
        dashpot model's collisions are exact, or from the surrogate tables of `level`."""
        law_params = [rows[:, i] for i in range(len(self.law.parameters))]

        def finite(speed):
            speed = np.asarray(speed, dtype=float)
            bad = ~np.isfinite(speed)
            if bad.any():
                np.logical_or(broken, bad, out=broken)
            return np.where(bad, 0.0, speed)

        def rebound(speed):
            return self.law.rebound(finite(speed), *law_params)

        contact = None
        if self.law.contact is not None:
            rebound, contact = self._contact_maps(law_params, finite, level)
        flight = self.flight_of(rows)
        return TrainModel(rebound, lambda v: flight(finite(v)), contact)

    def _contact_maps(self, law_params, finite=lambda speed: speed, level="exact"):
        """Rebound and contact-time maps of a law with a contact duration (a dashpot model)
        sharing one evaluation of its ``contact`` per speed array (the filter asks both at
        the same speeds, one after the other); exact or from the surrogate tables of
        `level`."""
        last = {}

        def both(speed):
            if last.get("speed") is not speed:
                last["speed"] = speed
                last["value"] = self.law.contact(finite(speed), *law_params, g=self.g,
                                                 level=level)
            return last["value"]

        return (lambda speed: both(speed)[:2]), (lambda speed: both(speed)[2:])

    def step_model(self, law_rows, level="exact"):
        """TrainModel of rows (sets, len(step_columns)) of the step map's parameters, for
        tabulation (its callables take speeds of shape (nodes, 1)); a dashpot model's
        collisions from the surrogate tables of `level` unless it is "exact"."""
        law_params = [law_rows[:, i] for i in range(len(self.law.parameters))]
        contact = None
        if self.law.contact is not None:
            rebound, contact = self._contact_maps(law_params, level=level)
        else:
            def rebound(speed):
                return self.law.rebound(speed, *law_params)
        return TrainModel(rebound, self.flight_of(law_rows), contact)

    def run_filter(self, rows, trains, broken=None, level=None):
        """Kalman filter of parameter rows (sets, P) against the trains at rows `trains`, at
        accuracy `level` (default the problem's). A step the tabulated map cannot give (off
        its grid, or next to a captured node) is evaluated directly at its speed and patched
        into the row's filter; a row that needs more than PATCHES of them is evaluated
        directly."""
        level = level or self.level
        broken = np.zeros(rows.shape[0], bool) if broken is None else broken
        if self.has_speeds:
            return self._run_speed_filter(rows, trains, broken, level)
        arguments = self._filter_arguments(rows, trains)
        if level == "exact":
            return self.model(rows, broken).filter(self.times[trains], **arguments)
        table, members = self.table(rows, level)
        result, off, stop = table.filter(self.times[trains], members=members, **arguments)
        index = np.flatnonzero(off)
        patches = [[] for _ in index]
        direct = []  # rows evaluated directly after all
        for attempt in range(PATCHES + 1):
            if not index.size:
                break
            # Where the table cannot give the step (next to a node where the ball is
            # captured, or off the grid), it is evaluated directly at that speed: where it is
            # not finite (captured) so is the direct filter's and the row is broken; else
            # the row runs again with that step patched in, up to PATCHES times, and then
            # directly.
            speeds = stop[index]
            usable = np.isfinite(speeds)
            step = self.step_model(rows[index][:, self.step_columns], level).step(
                np.where(usable, speeds, 0.0))
            captured = np.broadcast_to(step[-1], index.shape) & usable
            broken[index[captured]] = True
            result.neg2_log_likelihood[index[captured]] = np.inf
            patch = usable & ~captured & (attempt < PATCHES)
            direct.append(index[~captured & ~patch])
            patches = [previous + [(speed, [np.broadcast_to(q, index.shape)[k]
                                            for q in step[:6]])]
                       for k, (previous, speed) in enumerate(zip(patches, speeds)) if patch[k]]
            index = index[patch]
            if not index.size:
                break
            size = max(len(p) for p in patches)
            patch_speed = np.full((index.size, size), np.nan)
            patch_step = np.zeros((index.size, size, 6))
            for k, rows_patches in enumerate(patches):
                for m, (speed, values) in enumerate(rows_patches):
                    patch_speed[k, m], patch_step[k, m] = speed, values
            again, off, again_stop = table.filter(
                self.times[trains[index]], members=members[index],
                patches=(patch_speed, patch_step, np.array([len(p) for p in patches])),
                **self._filter_arguments(rows[index], trains[index]))
            for name in FILTER_FIELDS:
                getattr(result, name)[index] = getattr(again, name)
            stop[index] = again_stop
            patches = [p for p, still in zip(patches, off) if still]
            index = index[off]
        index = np.concatenate(direct + [index]).astype(int)
        if index.size:
            part = np.zeros(index.size, bool)
            exact = self.run_filter(rows[index], trains[index], part, "exact")
            broken[index] = part
            for name in FILTER_FIELDS:
                getattr(result, name)[index] = getattr(exact, name)
        return result

    def _run_speed_filter(self, rows, trains, broken, level):
        """The filter of :func:`_speed_filter` (times and measured speeds) of parameter rows
        (sets, P) against the trains at rows `trains`: the law and flight evaluated at every
        step, a dashpot model's collisions exact or from the surrogate tables of `level`."""
        process, jitter = (np.exp(rows[:, self.index(n)]) for n in ("sigma_eps", "sigma_j"))
        timing_variance = self.detector[trains] ** 2 + jitter[:, None] ** 2
        if self.speed_errors is not None:
            return _correlated_speed_filter(
                self.model(rows, broken, level), self.times[trains], timing_variance,
                self.impact_speed[trains], self.rebound_speed[trains],
                tuple(a[trains] for a in self.speed_errors), rows[:, self.index("v0")],
                process)
        return _speed_filter(self.model(rows, broken, level), self.times[trains],
                             timing_variance, self.impact_speed[trains],
                             self.rebound_speed[trains], self.speed_variance[trains],
                             rows[:, self.index("v0")], process)

    def _filter_arguments(self, rows, trains):
        """The filter's start, noise and detector arguments of parameter rows (sets, P)."""
        process, jitter = (np.exp(rows[:, self.index(n)]) for n in ("sigma_eps", "sigma_j"))
        return dict(start_time=None, start_speed=rows[:, self.index("v0")],
                    process_sigma=process, jitter=jitter, detector_sigma=self.detector[trains])

    def table(self, rows, level):
        """The step map of the distinct step parameters among `rows`, tabulated at `level`,
        and which of them each row uses."""
        keys = np.ascontiguousarray(rows[:, self.step_columns])
        # Rows as opaque bytes: np.unique of those is several times faster than over axis 0.
        _, first, members = np.unique(
            keys.view(np.dtype((np.void, keys.dtype.itemsize * keys.shape[1]))).ravel(),
            return_index=True, return_inverse=True)
        table = self.step_model(keys[first], level).tabulate(*self.grid, GRID_LOG_STEPS[level])
        return table, members.reshape(-1)

    def level_errors(self, row, t):
        """How far the problem's level is from the direct evaluation at parameter row `row`
        of train `t`.

        Returns
        -------
        relative : float
            Largest relative error of the tabulated duration to the next impact and of the
            next impact speed, at the quarter points of the grid intervals holding the
            train's speeds (where a cubic Hermite interpolant's error peaks).
        likelihood : float
            |Δ(−2 ln L)| between the level's filter and the direct one.
        timing : float
            Largest |Δ predicted time| in s.
        direct : TrainFilter
            The direct filter at the row.

        Notes
        -----
        The direct filter evaluates the exact step at each impact, one after the other (for
        a dashpot model a collision of its own per impact: 15 ms a train). Here the exact
        step is evaluated once, at every speed the level's filter passed through (and just
        beyond the extremes), and the filter is run over its Hermite interpolant between
        those speeds: the direct filter's speeds differ from them by the level's own error
        (about 1e-9 relative), where the interpolant, exact at the speeds with its slope,
        is off by the square of that. Where that filter still leaves its speeds it is run
        directly.
        """
        rows, trains = row[None, :], np.array([t])
        if self.level == "exact":
            return 0.0, 0.0, 0.0, self.run_filter(rows, trains, level="exact")
        if self.has_speeds:
            return self._speed_level_errors(rows, trains)
        tabulated = self.run_filter(rows, trains)
        speeds = tabulated.filtered_speeds[0]
        speeds = speeds[np.isfinite(speeds) & (speeds > 0.0)]
        direct = None
        if speeds.size:
            nodes = np.unique(np.concatenate([speeds, [speeds.min() * (1.0 - 1e-6),
                                                       speeds.max() * (1.0 + 1e-6)]]))
            replay = self.step_model(row[None, self.step_columns]).tabulate_at(nodes)
            direct, off, _ = replay.filter(self.times[trains], members=np.zeros(1, int),
                                           **self._filter_arguments(rows, trains))
            if off[0]:
                direct = None
        if direct is None:
            direct = self.run_filter(rows, trains, level="exact")
        table, _ = self.table(rows, self.level)
        inside = ((table.nodes[:-1] <= np.max(speeds, initial=0.0))
                  & (table.nodes[1:] >= np.min(speeds, initial=np.inf)))
        left, right = table.nodes[:-1][inside], table.nodes[1:][inside]
        probes = np.concatenate([left + f * (right - left) for f in (0.25, 0.5, 0.75)])
        relative = 0.0
        if probes.size:
            exact = self.step_model(row[None, self.step_columns]).step(probes[:, None])
            approx = table.interpolate(probes, 0)
            relative = _largest_relative_error([(approx[q], exact[q][:, 0]) for q in (0, 1)])
        return (relative, *_filter_differences(tabulated, direct), direct)

    def _speed_level_errors(self, rows, trains):
        """:meth:`level_errors` of the filter with measured speeds, which evaluates the law
        and flight at every step: only a dashpot model's collisions depend on the level
        (its surrogate tables); the relative error is theirs (rebound speed and contact
        time) at the filtered speeds."""
        tabulated = self.run_filter(rows, trains)
        if self.law.contact is None:
            return 0.0, 0.0, 0.0, tabulated
        direct = self.run_filter(rows, trains, level="exact")
        speeds = direct.filtered_speeds[0]
        speeds = speeds[np.isfinite(speeds) & (speeds > 0.0)]
        relative = 0.0
        if speeds.size:
            law_params = [rows[:, i] for i in range(len(self.law.parameters))]
            exact = self.law.contact(speeds, *law_params, g=self.g, level="exact")
            approx = self.law.contact(speeds, *law_params, g=self.g, level=self.level)
            relative = _largest_relative_error([(approx[q], exact[q]) for q in (0, 2)])
        return (relative, *_filter_differences(tabulated, direct), direct)

    def objective(self, rows, trains):
        """−2 ln L (priors included) of rows (B, R, P) against trains (B,) → (B, R); inf where
        a row is outside the bounds."""
        batch, count, size = rows.shape
        flat = rows.reshape(-1, size)
        train = np.repeat(trains, count)
        # The law's parameters and v0 inside their bounds (v0 > 0); ln σ anything but NaN or
        # +inf (its bounds limit the steps only, so that the stencil may straddle the floor;
        # −inf is a noise source fixed at 0).
        bounded = self.law_count + 1
        inside = flat[:, :bounded]
        valid = (np.all(np.isfinite(inside), axis=1)
                 & np.all(inside >= self.lower[:bounded], axis=1)
                 & np.all(inside <= self.upper[:bounded], axis=1)
                 & (flat[:, self.index("v0")] > 0.0)
                 & np.all(np.isfinite(flat[:, bounded:]) | np.isneginf(flat[:, bounded:]),
                          axis=1))
        out = np.full(flat.shape[0], np.inf)
        if valid.any():
            chosen = flat[valid]
            broken = np.zeros(chosen.shape[0], bool)
            with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
                value = self.run_filter(chosen, train[valid], broken).neg2_log_likelihood
            value = np.where(broken, np.inf, value)
            for name, centre, sd in self.priors:
                value = value + ((chosen[:, self.index(name)] - centre) / sd) ** 2
            out[valid] = np.where(np.isfinite(value), value, np.inf)
        return out.reshape(batch, count)

    # --- start values -----------------------------------------------------------------------

    def starts(self):
        """Start rows (trains, P) of the law and v0; the noise columns are set by the caller."""
        rows = np.zeros((len(self.datasets), len(self.names)))
        for row, d in enumerate(self.datasets):
            rows[row] = self._start(d)
        for name, value in self.fixed.items():
            rows[:, self.index(name)] = value
        return rows

    def _start(self, data):
        intervals = np.diff(data.times) / np.diff(data.index)
        eps = _flight_ratio_start(intervals, data.interval_flags[: intervals.size])
        flight_start, flight = dict(self.flight_start), self.flight
        measured = self._flight_from_speeds(data) if self.has_speeds else None
        if measured is not None:
            # The flight's parameters from the measured speeds; the interval ratio is ε times
            # the flight's speed ratio √(a_toward/a_away) (no drag: see _flight_from_speeds).
            flight_start.update(measured)
            row = np.array([[*([0.0] * len(self.law.parameters)), *flight_start.values()]])
            flight = self.flight_of(row)
            track = flight_track(self.flight_effects, self.g, flight_start)
            eps = float(np.clip(eps / math.sqrt(track.down / track.up), 1e-3, 1.0 - 1e-9))
        # The rebound after the first impact from its flight: T(v) = first interval, by Newton
        # steps on the flight law (gravity or drag) from the gravity value.
        rebound = 0.5 * self.g * intervals[0]
        for _ in range(8):
            flight_now = flight(np.array([rebound]))
            rebound = max(rebound - float(flight_now.duration[0] - intervals[0])
                          / float(flight_now.duration_slope[0]), 1e-6)
        v0 = self.fixed.get("v0", rebound / eps)
        typical = v0 * eps ** (0.5 * data.count)
        start = {p.name: p.start for p in self.law.parameters}
        name = self.law.contact_model
        if name is not None:
            # A dashpot model's: from its deterministic fits.
            known = self.fixed.get("v_star")
            # Start values from the deterministic trains, by the fast surrogate trains at the
            # tabulated levels (a start needs no more).
            solver = {} if self.level == "exact" else dict(
                trains_solver=_trains_solver("fast", name)[0])
            values, how = _start_values(name, data, v0 if "v0" in self.fixed else None,
                                        None if known is None else self.g / known,
                                        fit_v0="v0" not in self.fixed, **solver)
            if values is None:
                raise ValueError(f"no start values: {how}")
            start["zeta"], start["v_star"] = values["zeta"], self.g / values["omega0"]
            v0 = values["v0"]
        elif self.law.start is not None:
            # The law's own, from the first flights' restitution and a typical speed.
            start.update(self.law.start(eps, typical))
        return ([start[p] for p in self.law.parameter_names] + list(flight_start.values())
                + [v0, 0.0, 0.0])

    def _flight_from_speeds(self, data):
        """Start values of the flight's parameters of a train with measured speeds, from its
        one effect's ``speed_start`` (:class:`dashpot.physics.effects.FlightEffect`); None
        where the fit carries no such effect alone, or fewer than two flights have both ends
        measured."""
        if len(self.flight_effects) != 1 or self.flight_effects[0].speed_start is None:
            return None
        effect = self.flight_effects[0]
        flights = np.flatnonzero(np.diff(data.index) == 1)
        launch, landing = data.rebound_speed[flights], data.impact_speed[flights + 1]
        duration = np.diff(data.times)[flights]
        usable = (np.isfinite(launch) & np.isfinite(landing) & (launch > 0.0)
                  & (landing > 0.0) & (duration > 0.0))
        if np.sum(usable) < 2:
            return None
        columns = {name: (self.flight_start[name], self.lower[self.index(name)],
                          self.upper[self.index(name)]) for name in effect.parameter_names}
        return effect.speed_start(launch[usable], landing[usable], duration[usable], columns)

    def units(self, rows):
        """Initial coordinate units (about a standard error) of every parameter, per row."""
        units = np.empty(rows.shape)
        law_count = len(self.law.parameters)
        for i in range(law_count):
            span = self.upper[i] - self.lower[i]
            units[..., i] = np.where(rows[..., i] != 0.0, 1e-3 * np.abs(rows[..., i]),
                                     1e-4 * span)
        # The flight's: each parameter's own step (EffectParameter.step), else 1e-3 of g.
        steps = {parameter.name: parameter.step for effect in self.flight_effects
                 for parameter in effect.parameters}
        for name in self.flight_start:
            step = steps.get(name)
            units[..., self.index(name)] = 1e-3 * self.g if step is None else step
        law_count = self.law_count
        units[..., law_count] = 1e-3 * np.abs(rows[..., law_count])
        units[..., law_count + 1:] = 0.3
        return units


@dataclass(frozen=True)
class SpeedTrainFilter(TrainFilter):
    """Output of :func:`_speed_filter`: that of :class:`dashpot.likelihood.TrainFilter` (the
    impact times' innovations; ``neg2_log_likelihood`` of times and speeds together) and the
    measured speeds' innovations.

    Attributes
    ----------
    speed_innovations : ndarray, shape (batch, impacts, 2)
        Measured less predicted impact speed u_n and rebound speed v_n (m/s), each predicted
        from everything observed before it; NaN where not measured.
    speed_variance : ndarray, shape (batch, impacts, 2)
        Their predicted variances (m²/s²): the state's plus the measurement's.
    speed_scored : ndarray of bool, shape (batch, impacts, 2)
        Where a speed was measured (and scored).
    """

    speed_innovations: np.ndarray = None
    speed_variance: np.ndarray = None
    speed_scored: np.ndarray = None

    @property
    def speed_standardized(self):
        """Speed innovations over their predicted σ, NaN where not measured."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return self.speed_innovations / np.sqrt(self.speed_variance)



def _filter_buffers(process, batch, count):
    """The speed filters' per-row process noise (laid out for `batch` rows), flags and sums,
    and their outputs over `count` impacts: innovations, their variances, predicted times and
    speeds and filtered speeds (NaN until written), which times and speeds were scored."""
    process = np.ascontiguousarray(np.broadcast_to(np.asarray(process, float), (batch,)))
    anchored = np.zeros(batch, np.bool_)
    total = np.zeros(batch)
    broken = np.zeros(batch, np.bool_)
    out = np.full((5, batch, count), np.nan)
    scored = np.zeros((batch, count), np.bool_)
    speed_out = np.full((2, batch, count, 2), np.nan)
    speed_scored = np.zeros((batch, count, 2), np.bool_)
    return process, anchored, total, broken, out, scored, speed_out, speed_scored


def _filter_result(total, broken, out, scored, speed_out, speed_scored):
    """The SpeedTrainFilter of the speed filters' buffers (:func:`_filter_buffers`): −2 ln L
    is inf for a row whose train broke or left the finite numbers."""
    total = np.where(broken | np.isnan(total), np.inf, total)
    return SpeedTrainFilter(
        neg2_log_likelihood=total, innovations=out[0], innovation_variance=out[1],
        predicted_times=out[2], predicted_speeds=out[3], filtered_speeds=out[4],
        scored=scored, speed_innovations=speed_out[0], speed_variance=speed_out[1],
        speed_scored=speed_scored)


def _bounce_columns(model, speed):
    """Rebound speed, its slope, contact time and its slope (rows) at each row's filtered
    impact `speed` (m/s), as the speed filters' bounce steps take them."""
    rebound, rebound_slope = model.rebound(speed)
    contact, contact_slope = (0.0, 0.0) if model.contact_time is None else \
        model.contact_time(speed)
    columns = np.empty((4, np.size(speed)))
    columns[0], columns[1], columns[2], columns[3] = (rebound, rebound_slope, contact,
                                                      contact_slope)
    return columns

def _speed_filter(model, times, timing_variance, impact_speed, rebound_speed, speed_variance,
                  start_speed, process):
    """Extended Kalman filter of impact trains over their impact times and measured speeds.

    The model is that of :class:`dashpot.likelihood.TrainModel` (bounce v_n = R(u_n)(1 + η_n),
    η_n ~ N(0, σ_ε²); flight t_{n+1} = t_n + τ(u_n) + T(v_n), u_{n+1} = L(v_n); timing
    noise on each t_n), with two more observations of each impact, as a motion sensor gives
    them: the impact speed u_n and the rebound speed v_n, each with Gaussian noise of
    variance σ_v,n². The step is therefore split at the bounce: after the updates of impact
    n (its time, then its impact speed) the state (t_n, u_n) is carried through the contact
    and the bounce to (s_n, v_n), s_n = t_n + τ(u_n) the end of the contact, the process
    noise entering there (var v_n gains (R σ_ε)²); it is updated with the rebound speed and
    carried through the flight to (t_{n+1}, u_{n+1}). Each step is linearized about the
    current estimate (the extended filter [1]_ §10.2), and the observations of one impact,
    with independent noises, are taken one at a time (sequential processing [1]_ §6.4).
    Without a rebound speed the two halves compose to the step of
    :meth:`dashpot.likelihood.TrainModel.filter`. The flight between a rebound and the next
    impact is where friction and drag act: v_n and u_{n+1}, both measured, differ by L, which
    is what lets the speeds see them apart from ε.

    The start time is integrated out (flat prior: the first observed time anchors it and
    scores nothing), the start speed u_0 is a parameter (variance 0).

    Parameters
    ----------
    model : TrainModel
        Rebound, flight and contact time of each row (its callables broadcast over rows).
    times : ndarray, shape (batch, impacts)
        Measured impact times in s; NaN where missed.
    timing_variance : ndarray, shape (batch, impacts)
        Variance of each time's noise in s².
    impact_speed, rebound_speed : ndarray, shape (batch, impacts)
        Measured speeds in m/s; NaN where not measured.
    speed_variance : ndarray, shape (batch, impacts)
        σ_v,n² in m²/s² of both speeds of impact n.
    start_speed, process : ndarray, shape (batch,)
        u_0 in m/s and σ_ε.

    Returns
    -------
    SpeedTrainFilter
        −2 ln L = Σ [r²/S + ln(2π S)] over every scored time and speed; inf for a row whose
        train left the finite numbers.

    References
    ----------
    .. [1] J. Durbin and S. J. Koopman, *Time Series Analysis by State Space Methods*, 2nd
       ed., Oxford University Press (2012).
    """
    batch, count = times.shape
    # The state of every row: t, u (or s, v after the bounce), P_tt, P_tu, P_uu.
    state = np.zeros((5, batch))
    state[0] = np.nan
    state[1] = start_speed
    process, anchored, total, broken, out, scored, speed_out, speed_scored = _filter_buffers(
        process, batch, count)
    arrays = [np.ascontiguousarray(a, dtype=float) for a in (
        times, timing_variance, impact_speed, rebound_speed, speed_variance)]
    times, timing_variance, impact_speed, rebound_speed, speed_variance = arrays
    for n in range(count):
        # Impact n: its time (as in TrainModel.filter), then its impact speed.
        _impact_update(n, state, anchored, times, timing_variance, impact_speed,
                       speed_variance, total, out, scored, speed_out, speed_scored)
        # The contact and the bounce at the filtered speed, then the rebound speed.
        speed, _ = _finite_speed(np.maximum(state[1], 0.0))
        columns = _bounce_columns(model, speed)
        _bounce_update(n, state, columns, process, rebound_speed, speed_variance, total,
                       broken, speed_out, speed_scored)
        if n == count - 1:
            break
        # The flight to impact n + 1.
        flight = model.flight(np.maximum(state[1], 0.0))
        columns = np.empty((4, batch))
        columns[0], columns[1], columns[2], columns[3] = (
            flight.duration, flight.landing_speed, flight.duration_slope, flight.landing_slope)
        _flight_predict(state, columns, broken)
    return _filter_result(total, broken, out, scored, speed_out, speed_scored)


def _correlated_speed_filter(model, times, timing_variance, impact_speed, rebound_speed,
                             errors, start_speed, process):
    """The filter of :func:`_speed_filter` where the measured speeds' errors are correlated
    as a motion reader states them (:class:`dashpot.fit.results.SpeedErrors`).

    The state (t, u) is augmented with the run's shared errors z_1..z_r, constant states of
    prior N(0, 1), and with the current flight's own error w, prior N(0, 1), drawn afresh
    after each impact speed: the impact speed of impact n observes u + Σ_j a_nj·z_j + b_n·w
    (w the flight before it) with independent noise of variance σ_in,n², its rebound speed
    v + Σ_j c_nj·z_j + d_n·w (w the flight after it) with σ_out,n². For a linear Gaussian
    train this is the exact likelihood (the augmented state's Kalman filter [1]_ §6.2.3: the
    constant states are the regression effects of de Jong's augmentation); the step,
    linearization and start are those of :func:`_speed_filter`, and with r = 0 and no own
    correlation it computes what that does.

    Parameters
    ----------
    model, times, timing_variance, impact_speed, rebound_speed, start_speed, process
        As in :func:`_speed_filter`.
    errors : tuple of ndarray
        (shared_in, shared_out) of shape (batch, impacts, r): a_nj, c_nj in m/s;
        (flight_in, flight_out) of shape (batch, impacts): b_n, d_n in m/s; (in_variance,
        out_variance) of shape (batch, impacts): σ_in,n², σ_out,n² in m²/s² (NaN where the
        speed is not measured).

    Returns
    -------
    SpeedTrainFilter

    References
    ----------
    .. [1] J. Durbin and S. J. Koopman, *Time Series Analysis by State Space Methods*, 2nd
       ed., Oxford University Press (2012).
    """
    batch, count = times.shape

    def laid_out(a, shape):
        a = np.asarray(a, dtype=float)
        return np.ascontiguousarray(a if a.shape == shape else np.broadcast_to(a, shape))

    shared_in, shared_out = (laid_out(a, (batch, count, np.shape(a)[-1])) for a in errors[:2])
    flight_in, flight_out, in_variance, out_variance = (laid_out(a, (batch, count))
                                                        for a in errors[2:])
    size = 3 + shared_in.shape[2]  # t, u, z_1..z_r, w
    state = np.zeros((batch, size))
    state[:, 0] = np.nan
    state[:, 1] = start_speed
    cov = np.zeros((batch, size, size))
    cov[:, 2:, 2:] = np.eye(size - 2)
    process, anchored, total, broken, out, scored, speed_out, speed_scored = _filter_buffers(
        process, batch, count)
    times, timing_variance, impact_speed, rebound_speed = (
        np.ascontiguousarray(a, dtype=float)
        for a in (times, timing_variance, impact_speed, rebound_speed))
    work = np.zeros((2, size))
    for n in range(count):
        _augmented_impact(n, state, cov, anchored, times, timing_variance, impact_speed,
                          shared_in, flight_in, in_variance, total, out, scored, speed_out,
                          speed_scored, work)
        speed, _ = _finite_speed(np.maximum(state[:, 1], 0.0))
        columns = _bounce_columns(model, speed)
        _augmented_step(n, state, cov, columns, process, broken, True, rebound_speed,
                        shared_out, flight_out, out_variance, total, speed_out, speed_scored,
                        work)
        if n == count - 1:
            break
        flight = model.flight(np.maximum(state[:, 1], 0.0))
        columns = np.empty((4, batch))
        columns[0], columns[1], columns[2], columns[3] = (
            flight.landing_speed, flight.landing_slope, flight.duration, flight.duration_slope)
        _augmented_step(n, state, cov, columns, process, broken, False, rebound_speed,
                        shared_out, flight_out, out_variance, total, speed_out, speed_scored,
                        work)
    return _filter_result(total, broken, out, scored, speed_out, speed_scored)


@numba.njit(cache=True)
def _augmented_update(x, p, b, h, ph, noise, measured):
    """Kalman update of row b's state x[b] (covariance p[b], both in place) with a scalar
    measurement h·x[b] of variance `noise` (`ph` scratch space of the state's size); returns
    (innovation, its variance, −2 ln L term), the term inf and the state unchanged where the
    innovation has no variance. Entries of the state where h is 0 do not enter the
    prediction (the diffuse start time is NaN until anchored)."""
    size = x.shape[1]
    predicted = 0.0
    for j in range(size):
        ph[j] = 0.0
    for i in range(size):
        if h[i] != 0.0:
            predicted += h[i] * x[b, i]
            for j in range(size):
                ph[j] += p[b, j, i] * h[i]
    variance = noise
    for i in range(size):
        variance += h[i] * ph[i]
    r = measured - predicted
    if not variance > 0.0:
        return r, variance, math.inf
    for i in range(size):
        gain = ph[i] / variance
        x[b, i] += gain * r
        for j in range(size):
            p[b, i, j] -= gain * ph[j]
        p[b, i, i] = max(p[b, i, i], 0.0)  # what rounding may leave below 0 of a variance
    return r, variance, r * r / variance + math.log(variance) + LOG_TWO_PI


@numba.njit(cache=True)
def _augmented_speed(n, which, b, state, cov, speed, shared, flight, variance, total,
                     speed_out, speed_scored, work):
    """The measured speed of impact n (`which` 0: impact speed, 1: rebound speed) taken
    into row b's augmented state: u + Σ_j shared_j·z_j + flight·w, noise `variance`."""
    measured, noise = speed[b, n], variance[b, n]
    if not (math.isfinite(measured) and math.isfinite(noise)):
        return
    size = state.shape[1]
    h = work[0]
    h[:] = 0.0
    h[1] = 1.0
    for j in range(shared.shape[2]):
        h[2 + j] = shared[b, n, j]
    h[size - 1] = flight[b, n]
    r, s, term = _augmented_update(state, cov, b, h, work[1], noise, measured)
    speed_out[0, b, n, which], speed_out[1, b, n, which] = r, s
    speed_scored[b, n, which] = True
    total[b] += term


@numba.njit(cache=True)
def _augmented_impact(n, state, cov, anchored, times, timing_variance, impact_speed, shared,
                      flight, variance, total, out, scored, speed_out, speed_scored, work):
    """Impact n of every row of :func:`_correlated_speed_filter`: its time (the diffuse start
    anchored by the first observed one, as :func:`dashpot.likelihood._observe_time`), its
    impact speed, then the flight's own error w drawn afresh for the flight after it."""
    size = state.shape[1]
    for b in range(state.shape[0]):
        out[2, b, n], out[3, b, n] = state[b, 0], state[b, 1]
        y, timing = times[b, n], timing_variance[b, n]
        if math.isfinite(y):
            if anchored[b]:
                h = work[0]
                h[:] = 0.0
                h[0] = 1.0
                r, s, term = _augmented_update(state, cov, b, h, work[1], timing, y)
                out[0, b, n], out[1, b, n] = r, s
                scored[b, n] = True
                total[b] += term
            else:
                state[b, 0] = y
                cov[b, 0, :] = 0.0
                cov[b, :, 0] = 0.0
                cov[b, 0, 0] = timing
                anchored[b] = True
        _augmented_speed(n, 0, b, state, cov, impact_speed, shared, flight, variance, total,
                         speed_out, speed_scored, work)
        out[4, b, n] = state[b, 1]
        state[b, size - 1] = 0.0
        cov[b, size - 1, :] = 0.0
        cov[b, :, size - 1] = 0.0
        cov[b, size - 1, size - 1] = 1.0


@numba.njit(cache=True)
def _augmented_step(n, state, cov, columns, process, broken, bounce, speed, shared, flight,
                    variance, total, speed_out, speed_scored, work):
    """(t, u) → (t + D, S) of every row, linearized (∂/∂u: `columns` holding S, dS/du, D,
    dD/du): the contact and bounce of impact n (`bounce`: S = R(u)(1 + η), the process noise
    entering, D = τ(u)), then its measured rebound speed; or the flight (S = L(v), D = T(v)).
    A row whose step is not finite is marked broken and carried on with the step put at 0."""
    size = state.shape[1]
    for b in range(state.shape[0]):
        value, slope, duration, duration_slope = (columns[0, b], columns[1, b], columns[2, b],
                                                  columns[3, b])
        if not (math.isfinite(state[b, 1]) and math.isfinite(value) and math.isfinite(slope)
                and math.isfinite(duration) and math.isfinite(duration_slope)):
            broken[b] = True
            value = slope = duration = duration_slope = 0.0
        for j in range(size):  # F·P, then (F·P)·Fᵀ
            cov[b, 0, j] += duration_slope * cov[b, 1, j]
            cov[b, 1, j] *= slope
        for i in range(size):
            cov[b, i, 0] += duration_slope * cov[b, i, 1]
            cov[b, i, 1] *= slope
        state[b, 0] += duration
        state[b, 1] = value
        if bounce:
            kick = value * process[b]
            cov[b, 1, 1] += kick * kick
            _augmented_speed(n, 1, b, state, cov, speed, shared, flight, variance, total,
                             speed_out, speed_scored, work)


@numba.njit(cache=True)
def _observe_speed(v, p_vv, p_vt, p_tt, t, measured, noise, b, n, which, total, speed_out,
                   speed_scored):
    """A measured speed (impact speed: `which` 0, rebound speed: 1; variance `noise`) taken
    into the state (v, t) of row b at impact n by :func:`dashpot.likelihood._observe`, its
    innovation, variance and −2 ln L term recorded; the state unchanged where it is missing.
    Returns (v, P_vv, P_vt, P_tt, t)."""
    if math.isfinite(measured) and math.isfinite(noise):
        v, p_vv, p_vt, p_tt, t, r, variance, term = _observe(v, p_vv, p_vt, p_tt, t,
                                                             measured, noise)
        speed_out[0, b, n, which], speed_out[1, b, n, which] = r, variance
        speed_scored[b, n, which] = True
        total[b] += term
    return v, p_vv, p_vt, p_tt, t


@numba.njit(cache=True)
def _impact_update(n, state, anchored, times, timing_variance, impact_speed, speed_variance,
                   total, out, scored, speed_out, speed_scored):
    """Impact n of every row of :func:`_speed_filter`: its time (the arithmetic of
    :meth:`dashpot.likelihood.TrainModel.filter`, a diffuse start time anchored by the first
    observed one), then its measured impact speed; the outputs recorded."""
    for b in range(state.shape[1]):
        t, u, p_tt, p_tu, p_uu = state[0, b], state[1, b], state[2, b], state[3, b], state[4, b]
        out[2, b, n], out[3, b, n] = t, u
        (scored[b, n], anchored[b], out[0, b, n], out[1, b, n], term,
         t, u, p_tt, p_tu, p_uu) = _observe_time(times[b, n], timing_variance[b, n],
                                                 anchored[b], t, u, p_tt, p_tu, p_uu)
        total[b] += term
        u, p_uu, p_tu, p_tt, t = _observe_speed(u, p_uu, p_tu, p_tt, t, impact_speed[b, n],
                                                speed_variance[b, n], b, n, 0, total,
                                                speed_out, speed_scored)
        out[4, b, n] = u
        state[0, b], state[1, b], state[2, b], state[3, b], state[4, b] = t, u, p_tt, p_tu, p_uu


@numba.njit(cache=True)
def _bounce_update(n, state, columns, process, rebound_speed, speed_variance, total, broken,
                   speed_out, speed_scored):
    """The contact and bounce of impact n of every row of :func:`_speed_filter`, linearized:
    (t, u) → (s, v) with s = t + τ(u), v = R(u)(1 + η), `columns` holding R, dR/du, τ, dτ/du
    at the filtered speeds; then the update with the measured rebound speed. A row whose
    step is not finite is marked broken and carried on with the step put at 0."""
    for b in range(state.shape[1]):
        t, p_tt, p_tu, p_uu = state[0, b], state[2, b], state[3, b], state[4, b]
        rebound, slope, contact, contact_slope = (columns[0, b], columns[1, b], columns[2, b],
                                                  columns[3, b])
        if not (math.isfinite(state[1, b]) and math.isfinite(rebound)
                and math.isfinite(slope) and math.isfinite(contact)
                and math.isfinite(contact_slope)):
            broken[b] = True
            rebound = slope = contact = contact_slope = 0.0
        kick = rebound * process[b]
        t = t + contact
        p_tt, p_tu, p_uu = (p_tt + 2.0 * contact_slope * p_tu + contact_slope * contact_slope
                            * p_uu, slope * (p_tu + contact_slope * p_uu),
                            slope * slope * p_uu + kick * kick)
        v, p_uu, p_tu, p_tt, t = _observe_speed(rebound, p_uu, p_tu, p_tt, t,
                                                rebound_speed[b, n], speed_variance[b, n],
                                                b, n, 1, total, speed_out, speed_scored)
        state[0, b], state[1, b], state[2, b], state[3, b], state[4, b] = t, v, p_tt, p_tu, p_uu


@numba.njit(cache=True)
def _flight_predict(state, columns, broken):
    """The flight of every row of :func:`_speed_filter` from (s, v) to the next impact
    (t, u), `columns` holding T, L, dT/dv, dL/dv at the rebound speeds; linearized."""
    for b in range(state.shape[1]):
        duration, landing, d_slope, l_slope = (columns[0, b], columns[1, b], columns[2, b],
                                               columns[3, b])
        if not (math.isfinite(duration) and math.isfinite(landing) and math.isfinite(d_slope)
                and math.isfinite(l_slope)):
            broken[b] = True
            duration = landing = d_slope = l_slope = 0.0
        p_tt, p_tv, p_vv = state[2, b], state[3, b], state[4, b]
        state[2, b] = p_tt + 2.0 * d_slope * p_tv + d_slope * d_slope * p_vv
        state[3, b] = l_slope * (p_tv + d_slope * p_vv)
        state[4, b] = l_slope * l_slope * p_vv
        state[0, b] += duration
        state[1, b] = landing
