"""Impacts of a cart (or ball) from position exports: PASCO Capstone and Vernier motion
sensors, Tracker video analysis.

References
----------
.. [4] P. J. Rousseeuw and C. Croux, "Alternatives to the median absolute deviation", J. Am.
   Stat. Assoc. 88, 1273-1283 (1993): σ ≈ 1.4826·MAD for Gaussian noise.
.. [5] D. Halliday, R. Resnick and J. Walker, "Fundamentals of Physics", ch. 2: motion with
   constant acceleration, x = x0 + v0·t + a·t²/2, v² = v0² + 2a·Δx.
.. [6] W. K. Newey and K. D. West, "A simple, positive semi-definite, heteroskedasticity and
   autocorrelation consistent covariance matrix", Econometrica 55, 703-708 (1987): least-squares
   uncertainties under serially correlated noise via the long-run variance.
.. [7] D. Brown, Tracker video analysis and modeling tool, help pages "Exporting data" and
   "Datatable view": the data export is tab-delimited text, a first line with the track name,
   a header row (``t``, ``x``, ``y``, ...), numbers as ``0.000000000E0``; derivatives are
   blank at a track's first and last steps.
.. [8] A. C. Aitken, "On least squares and linear combination of observations", Proc. R. Soc.
   Edinburgh 55, 42-48 (1935): generalized least squares under correlated errors.
"""

from __future__ import annotations

import re

import numpy as np
from scipy.integrate import cumulative_trapezoid
from scipy.linalg import LinAlgError, cho_factor, cho_solve
from scipy.sparse import csr_matrix

from .._validation import BUMPER_POSITION_RANGE, check_range
from ..errors import InputError
from ._tabular import (_POSITION_NAMES, _VELOCITY_NAMES, _check_duplicates, _impact_frame,
                       _runs, _table_of_kind)

_MAD_TO_SIGMA = 1.4826  # σ of Gaussian noise from its median absolute deviation [4]_
_MEDIAN_EFFICIENCY = 1.2533  # σ(median) = 1.2533·σ/√n for Gaussian samples, √(π/2)

# ---------------------------------------------------------------------------------------------
# Motion sensor
# ---------------------------------------------------------------------------------------------

def _mad_sigma(values):
    """Robust σ of Gaussian noise in `values` (median absolute deviation) [4]_."""
    values = values[np.isfinite(values)]
    if values.size == 0:
        return 0.0
    return float(_MAD_TO_SIGMA * np.median(np.abs(values - np.median(values))))


def _isolated_glitches(x, sigma):
    """Readings off both their neighbours by more than any motion around them allows.

    A motion sensor that loses its target for one ping (an echo off something else) writes
    one reading far from the cart. The reading k is such a glitch where its departure from
    the mean of its neighbours, |x_k − (x_{k−1} + x_{k+1})/2|, exceeds three times the
    largest step beside it, max(|x_{k−1} − x_{k−2}|, |x_{k+2} − x_{k+1}|), plus 8σ of the
    noise. A real turn cannot do that: at a reversal against the bumper the turning reading
    departs from its neighbours' mean by at most one step of the faster side, v·Δt, and in
    free flight by a·Δt² (constant acceleration [5]_); the steps beside a glitch are the
    cart's own.

    Parameters
    ----------
    x : numpy.ndarray
        Positions in m, in time order.
    sigma : float
        1σ position noise in m.

    Returns
    -------
    numpy.ndarray of bool
        True at the glitches (never at the first two or last two readings).
    """
    glitch = np.zeros(x.size, dtype=bool)
    if x.size < 5:
        return glitch
    departure = np.abs(x[2:-2] - 0.5 * (x[1:-3] + x[3:-1]))
    beside = np.maximum(np.abs(x[1:-3] - x[:-4]), np.abs(x[4:] - x[3:-1]))
    glitch[2:-2] = departure > 3.0 * beside + 8.0 * sigma
    return glitch


def _without_glitches(run, notes):
    """The run without its isolated glitch readings (see _isolated_glitches), noted."""
    if "position" not in run.columns:
        return run
    values, resolution = run.columns["position"]
    floor = float(np.nanmax(resolution)) / np.sqrt(12.0) if resolution.size else 0.0
    sigma = max(_mad_sigma(np.diff(values, 3)) / np.sqrt(20.0), floor)
    glitch = _isolated_glitches(values, sigma)
    if not glitch.any():
        return run
    keep = ~glitch
    notes.append(f"run '{run.label or 0}': {int(glitch.sum())} isolated reading(s) off both "
                 f"neighbours by more than three of the steps beside them left out (a lost "
                 f"echo of the sensor), at t = "
                 + ", ".join(f"{t:.4g} s" for t in run.time[glitch][:5])
                 + (" ..." if glitch.sum() > 5 else ""))
    columns = {key: ((value[0][keep], value[1][keep]) if isinstance(value, tuple) else
                     value[keep] if isinstance(value, np.ndarray) else value)
               for key, value in run.columns.items()}
    return type(run)(run.label, run.rows[keep], run.time[keep], columns)


def _runs_of(state):
    """Start, end (inclusive) and value of each run of equal values in an integer array."""
    change = np.flatnonzero(np.diff(state)) + 1
    starts = np.concatenate([[0], change])
    ends = np.concatenate([change - 1, [state.size - 1]])
    return starts, ends, state[starts]


def _first_extreme(values, starts, ends, which):
    """Index of the first maximum ('max') or minimum ('min') of `values` in each index run."""
    run_id = np.repeat(np.arange(starts.size), ends - starts + 1)
    reduce = np.maximum if which == "max" else np.minimum
    extreme = reduce.reduceat(values, starts)
    index = np.arange(values.size)
    return np.minimum.reduceat(np.where(values == extreme[run_id], index, values.size), starts)


def _bridge_gaps(state, starts, ends, values, max_gap):
    """`state` with each run of zeros of at most `max_gap` samples between two runs of the
    same sign given that sign: a dip of the noisy velocity into the noise band in the middle
    of a motion is no apex or contact (the velocity would have to change sign in between)."""
    lengths = ends - starts + 1
    before = np.concatenate([[0], values[:-1]])
    after = np.concatenate([values[1:], [0]])
    fill = (values == 0) & (lengths <= max_gap) & (before != 0) & (before == after)
    return np.where(np.repeat(fill, lengths), np.repeat(before, lengths), state)


_DETECTION_PERIOD = 0.02  # s: contacts are found on one (mean) sample per 20 ms at most


def _detection_step(dt):
    """Samples per detection block for a sampling period `dt` (s): the whole number nearest
    to _DETECTION_PERIOD/dt, at least 1.

    The reversals, flights and rest are found on a velocity over a time scale, not a sample
    count: central differences of samples Δt apart have noise σ_x/(√2·Δt), which at 100-400
    Hz buries a cart's slower bounces, and a soft contact's turn spans more samples than a
    reversal may. Means of `step` samples have noise σ_x/√step and their differences
    σ_x/(√(2·step)·step·Δt), so at every rate the detection sees the record as a sensor at
    about 50 Hz (the rate PASCO's motion sensor and Vernier's record at) with less noise.
    """
    return max(1, int(np.floor(_DETECTION_PERIOD / dt + 0.5)))


def _block_means(time, values, step):
    """Means of `values` over blocks of `step` consecutive samples (a trailing partial block
    left out), with each block's first and last time. With step 1, the values themselves."""
    if step == 1:
        return values, time, time
    blocks = time.size // step
    shaped = values[: blocks * step].reshape(blocks, step)
    times = time[: blocks * step].reshape(blocks, step)
    return shaped.mean(axis=1), times[:, 0], times[:, -1]


def _rest_start(s, sigma_x):
    """Index where the final rest begins: after the last sample that has moved from where the
    record ends (the median of its last 20 samples).

    A sample has moved if it lies more than 4σ from there with a neighbour more than 3σ on
    the same side, or more than 5.5σ alone: one sample of a resting cart's Gaussian noise
    beyond 4σ is a 1-in-16 000 event, which a long resting tail meets one run in a hundred,
    while beyond 5.5σ it is 1 in 26 million (and a neighbour beyond 3σ too, 1 in 10⁷).
    """
    offset = (s - np.median(s[-min(20, s.size):])) / sigma_x
    near = np.zeros(s.size, dtype=bool)  # a neighbour beyond 3σ on the same side
    same_high = (offset[1:] > 3.0) & (offset[:-1] > 3.0)
    same_low = (offset[1:] < -3.0) & (offset[:-1] < -3.0)
    both = same_high | same_low
    near[1:] |= both
    near[:-1] |= both
    moved = np.flatnonzero(((np.abs(offset) > 4.0) & near) | (np.abs(offset) > 5.5))
    return int(moved[-1]) + 1 if moved.size else 0


def _crossing(a, c, b, cov, bumper, var_bumper, incoming):
    """Where a fitted parabola meets the bumper position, with 1σ uncertainties.

    The parabola is s(τ) = c + b·τ + (a/2)·τ² about an edge sample (τ = 0), oriented so s
    grows toward the bumper and a > 0 is the free-motion acceleration toward it [5]_. With
    D = B − c the distance left, the speed there is V = √(b² + 2aD); the crossing is
    τ = 2D/(b + V) for the incoming branch (after the edge) and τ = −2D/(V − b) for the
    outgoing one (before it). Written this way neither form divides by a, which may be small.

    Returns (τ, V, σ_τ, σ_V); `cov` is the (…, 3, 3) covariance of (a, c, b).
    """
    distance = bumper - c
    speed2 = b ** 2 + 2.0 * a * distance
    with np.errstate(invalid="ignore", divide="ignore"):
        speed = np.sqrt(np.where(speed2 >= 0, speed2, np.nan))
        sign = 1.0 if incoming else -1.0
        denominator = sign * b + speed  # b + V incoming, V − b outgoing
        tau = sign * 2.0 * distance / denominator
        # Partial derivatives with respect to (a, c, b) and to the bumper position B.
        dv_dd, dv_db, dv_da = a / speed, b / speed, distance / speed
        dt_dd = sign * (2.0 / denominator - 2.0 * distance * dv_dd / denominator ** 2)
        dt_db = -sign * 2.0 * distance * (sign + dv_db) / denominator ** 2
        dt_da = -sign * 2.0 * distance * dv_da / denominator ** 2
    grad_t = np.stack([dt_da, -dt_dd, dt_db], axis=-1)
    grad_v = np.stack([dv_da, -dv_dd, dv_db], axis=-1)
    var_t = np.einsum("...i,...ij,...j->...", grad_t, cov, grad_t) + dt_dd ** 2 * var_bumper
    var_v = np.einsum("...i,...ij,...j->...", grad_v, cov, grad_v) + dv_dd ** 2 * var_bumper
    return tau, speed, np.sqrt(var_t), np.sqrt(var_v)


SHARED_ERRORS = 3
"""Shared errors of a run's speeds the motion reader states: its two leg accelerations (as
two independent components) and its bumper position."""


def _speed_gradient(a, c, b, bumper):
    """Gradient of the speed V = √(b² + 2a·(B − c)) at the bumper [5]_ with respect to (a, c,
    b) of the parabola at an edge, and ∂V/∂B (the derivatives of :func:`_crossing`)."""
    distance = bumper - c
    with np.errstate(invalid="ignore", divide="ignore"):
        speed = np.sqrt(b ** 2 + 2.0 * a * distance)
        return np.stack([distance / speed, -a / speed, b / speed], axis=-1), a / speed


def _shared_components(gradient, covariance, shared, bumper_slope, bumper_sd):
    """Split the errors of speeds fitted by least squares into run-level shared components
    and the rest.

    Parameters
    ----------
    gradient : ndarray, shape (m, p)
        ∂v/∂θ of m speeds (m/s) with respect to the fit's p parameters θ.
    covariance : ndarray, shape (p, p)
        Covariance of θ.
    shared : sequence of int
        Indices of the parameters every speed of the run depends on (the leg accelerations);
        the others are each flight's own.
    bumper_slope : ndarray, shape (m,)
        ∂v/∂B (1/s), B the bumper position, independent of θ with 1σ `bumper_sd` (m).

    Returns
    -------
    components : ndarray, shape (m, len(shared) + 1)
        Shift of each speed per +1σ of each shared error (m/s): the total derivative with
        respect to the shared parameters, dv/ds = ∂v/∂s + ∂v/∂l·Σ_ls·Σ_ss⁻¹ (the flights' own
        parameters l follow s as their conditional mean does), times the Cholesky factor of
        Σ_ss; then ∂v/∂B·σ_B.
    rest : ndarray, shape (m, m)
        Covariance of what is left, J·Σ·Jᵀ + σ_B²·∂v/∂B ∂v/∂Bᵀ − components·componentsᵀ: the
        flights' own errors given the shared parameters (Σ_ll − Σ_ls Σ_ss⁻¹ Σ_sl, block
        diagonal by flight for flights that share nothing else), so speeds of different
        flights have none of it in common.

    Notes
    -----
    For a linear Gaussian model e = J·δθ, δθ ~ N(0, Σ): δθ_l = Σ_ls Σ_ss⁻¹ δθ_s + δ', δ'
    independent of δθ_s with covariance Σ_ll − Σ_ls Σ_ss⁻¹ Σ_sl (the conditional Gaussian,
    e.g. C. M. Bishop, *Pattern Recognition and Machine Learning*, Springer (2006), sec.
    2.3.1).
    """
    gradient = np.nan_to_num(np.asarray(gradient, float))
    shared = np.asarray(shared, dtype=int)
    local = np.setdiff1d(np.arange(covariance.shape[0]), shared)
    s_s = covariance[np.ix_(shared, shared)]
    size = gradient.shape[0]
    with np.errstate(all="ignore"):
        try:
            factor = np.linalg.cholesky(s_s)
            follow = np.linalg.solve(s_s, covariance[np.ix_(shared, local)]).T  # Σ_ls Σ_ss⁻¹
        except np.linalg.LinAlgError:  # a degenerate fit: nothing stated
            return np.full((size, shared.size + 1), np.nan), np.full((size, size), np.nan)
        total = gradient[:, shared] + gradient[:, local] @ follow
        slope = np.nan_to_num(np.asarray(bumper_slope, float))
        components = np.column_stack([total @ factor, slope * bumper_sd])
        rest = (gradient @ covariance @ gradient.T + np.outer(slope, slope) * bumper_sd ** 2
                - components @ components.T)
    return components, rest


_FLOOR_TEST_SIGMAS = 3.0
"""One-sided significance (in σ of their difference) at which the resting tail and the
impacts' zero-speed meeting point are taken to disagree: a 0.13 % false alarm per run."""


def _zero_speed_meeting(meets, factor, covariance):
    """Bumper position from where each impact's incoming and outgoing parabolas meet,
    extrapolated to an instantaneous contact.

    Parameters
    ----------
    meets : ndarray, shape (m,)
        Position (m, growing toward the bumper) where each impact's two parabolas meet.
    factor : ndarray, shape (m,)
        v_in·v_out/(v_in + v_out) of each impact (m/s), from the parabolas' speeds there.
    covariance : ndarray, shape (m, m)
        Covariance of `meets` (m²).

    Returns
    -------
    tuple of float or None
        (B, var_B, T, var_T): the bumper position (m) and the contact duration (s) with their
        variances, by generalized least squares [8]_; the covariance is scaled by the reduced
        χ² where that exceeds 1. None with fewer than three meeting points (no degree of
        freedom left to check the model) or a singular system.

    Notes
    -----
    A contact of duration T between straight approach and departure at speeds v_in and v_out
    makes the extended parabolas meet T·v_in·v_out/(v_in + v_out) past the bumper [5]_
    (gravity adds terms of order a·T², negligible while a·T ≪ v). So
    meet_k = B + T·x_k, x_k = v_in·v_out/(v_in + v_out): the intercept B is where contact
    begins, whatever the contact's duration, unlike the meeting points themselves.
    """
    ok = np.isfinite(meets) & np.isfinite(factor)
    if ok.sum() < 3:
        return None
    meets, design = meets[ok], np.column_stack([np.ones(ok.sum()), factor[ok]])
    with np.errstate(all="ignore"):  # a noise-free record: a singular covariance, no answer
        try:
            factored = cho_factor(covariance[np.ix_(ok, ok)], check_finite=False)
            whitened = cho_solve(factored, np.column_stack([design, meets]), check_finite=False)
            normal = np.linalg.inv(design.T @ whitened[:, :2])
        except (LinAlgError, ValueError):
            return None
        theta = normal @ (design.T @ whitened[:, 2])
        residual = meets - design @ theta
        chi2 = float(residual @ cho_solve(factored, residual, check_finite=False))
        normal = normal * max(chi2 / (meets.size - 2), 1.0)
    if not (np.all(np.isfinite(normal)) and np.all(np.isfinite(theta)) and normal[0, 0] > 0):
        return None
    return float(theta[0]), float(normal[0, 0]), float(theta[1]), float(normal[1, 1])


def _floor_choice(rest, var_rest, meeting):
    """The bumper position from the resting tail or from the impacts' zero-speed meeting point.

    Parameters
    ----------
    rest, var_rest : float
        Median of the resting tail (m, growing toward the bumper) and its variance (m²).
    meeting : tuple or None
        :func:`_zero_speed_meeting`'s (B, var_B, T, var_T), or None.

    Returns
    -------
    tuple
        (bumper (m), variance (m²), verdict, z), z = (B − rest)/σ of their difference (NaN
        without a meeting point). Verdicts: "unchecked" (no meeting point: the tail);
        "moving" (z > _FLOOR_TEST_SIGMAS, the tail short of where contacts begin: bounces
        within the noise go on in it; B); "pressed" (z < −_FLOOR_TEST_SIGMAS, the tail past
        it: a soft bumper compressed by the resting cart, as documented; the tail); "agree"
        (the tail, the more precise) or "sharper" (B, the more precise).

    Notes
    -----
    Only a tail short of B is refused: bounces can only take a ball or cart away from the
    bumper, while a resting cart presses into a soft one. Of two that agree the more precise
    is used rather than their inverse-variance mean, which would shrink the stated σ while
    keeping part of the bias of a tail whose bounces lie just below the test's reach. On a
    soft bumper a cart's tail is the more precise (a handful of impacts with contacts of
    0.15 s extrapolate poorly to zero speed), so its reading is unchanged by the check; on a
    hard bumper (contacts of 11 ms) B often is, and a ball's hundred impacts place it more
    precisely than its tail.
    """
    if meeting is None or not var_rest + meeting[1] > 0:
        return rest, var_rest, "unchecked", np.nan
    position, variance = meeting[:2]
    z = (position - rest) / np.sqrt(var_rest + variance)
    if z > _FLOOR_TEST_SIGMAS:
        return position, variance, "moving", z
    if z < -_FLOOR_TEST_SIGMAS:
        return rest, var_rest, "pressed", z
    if variance < var_rest:
        return position, variance, "sharper", z
    return rest, var_rest, "agree", z


def _floor_note(label, orientation, choice, rest, var_rest, samples, meeting):
    """The note saying which bumper position a run's impacts are timed from, and why.

    `choice` is :func:`_floor_choice`'s answer, `rest`, `var_rest` and `samples` the resting
    tail's median (m, growing toward the bumper), its variance (m²) and size, `meeting`
    :func:`_zero_speed_meeting`'s (or None). Positions are stated on the file's axis.
    """
    bumper, variance, verdict, z = choice
    tail = (f"the resting tail ({samples} samples; a soft bumper's static compression under "
            f"the cart's weight is included)")
    if verdict == "unchecked":
        return (f"run '{label}': bumper position {orientation * bumper:.5g} m from {tail}; too "
                f"few impacts with free motion on both sides to check it against where their "
                f"parabolas meet")
    position, var_meet, duration, var_duration = meeting
    meet = (f"where the impacts' incoming and outgoing parabolas meet, extrapolated to an "
            f"instantaneous contact ({orientation * position:.5g} m ± "
            f"{1e3 * np.sqrt(var_meet):.2g} mm; contact {1e3 * duration:.3g} ± "
            f"{1e3 * np.sqrt(var_duration):.2g} ms)")
    if verdict in ("moving", "sharper"):
        why = (f"lies {z:.1f}σ short of it, so it still holds bounces within the noise"
               if verdict == "moving" else f"agrees ({z:+.1f}σ) but is less precise")
        return (f"run '{label}': bumper position {orientation * bumper:.5g} m {meet}: the "
                f"resting tail ({samples} samples, {orientation * rest:.5g} m ± "
                f"{1e3 * np.sqrt(var_rest):.2g} mm) {why}")
    relation = (f"agrees with {meet} ({z:+.1f}σ)" if verdict == "agree" else
                f"lies {-z:.1f}σ past {meet}: a bumper pressed by the resting cart")
    return (f"run '{label}': bumper position {orientation * bumper:.5g} ± "
            f"{1e3 * np.sqrt(variance):.2g} mm from {tail}, which {relation}")


def _motion_run(run, bumper_position, notes, legs):
    """Impacts of one run: arrays (time, σ_time, impact speed, rebound speed, σ_speed, flag)."""
    empty = (tuple(np.empty(0) for _ in range(5)) + (np.empty(0, dtype=str),)
             + _no_speed_errors(0))
    full_time = run.time
    full_n = full_time.size
    if full_n < 12:
        notes.append(f"run '{run.label or 0}': only {full_n} samples, no impacts looked for")
        return empty
    # Contacts, flights and rest are found on means of `step` consecutive samples, one per
    # detection period (see _detection_step); every sample is fitted.
    step = _detection_step(float(np.median(np.diff(full_time))))
    time, block_first, block_last = _block_means(full_time, full_time, step)
    n = time.size
    if n < 12:
        notes.append(f"run '{run.label or 0}': only {n} samples of {step} at the detection "
                     f"period, no impacts looked for")
        return empty
    if step > 1:
        notes.append(f"run '{run.label or 0}': sampled at {1.0 / np.median(np.diff(full_time)):.4g}"
                     f" Hz: contacts found on means of {step} consecutive samples (one per "
                     f"{1e3 * _DETECTION_PERIOD:.0f} ms), flights fitted on every sample")
    dt = float(np.median(np.diff(time)))
    if "position" in run.columns:
        full_x, x_res = run.columns["position"]
        x = _block_means(full_time, full_x, step)[0]
        # Velocity by central differences of the position: its noise statistics are then
        # known (σ_v = σ_x/(√2·Δt)), unlike a vendor's smoothed derivative. The third
        # differences of a parabola vanish, so their spread is noise: var(Δ³x) = 20σ_x²
        # (block means of a parabola are a parabola plus a constant: theirs vanish too).
        w_raw = np.gradient(x, time)
        floor = float(np.nanmax(x_res)) / np.sqrt(12.0)
        sigma_x = max(_mad_sigma(np.diff(x, 3)) / np.sqrt(20.0), floor)
        full_sigma_x = max(_mad_sigma(np.diff(full_x, 3)) / np.sqrt(20.0), floor)
        sigma_w = sigma_x / (np.sqrt(2.0) * dt)
        threshold, guard = 4.0 * sigma_w, 1
    else:
        full_v, v_res = run.columns["velocity"]
        # Velocity only: position up to a constant by integrating it (trapezoid rule). The
        # vendor's smoothing is unknown, so the threshold and guard are more generous.
        full_x = cumulative_trapezoid(full_v, full_time, initial=0.0)
        x = _block_means(full_time, full_x, step)[0]
        v = _block_means(full_time, full_v, step)[0]
        w_raw = v
        sigma_w = max(_mad_sigma(np.diff(v, 2)) / np.sqrt(6.0),
                      float(np.nanmax(v_res)) / np.sqrt(12.0))
        sigma_x = sigma_w * dt
        full_sigma_x = max(_mad_sigma(np.diff(full_v, 2)) / np.sqrt(6.0),
                           float(np.nanmax(v_res)) / np.sqrt(12.0)) * float(
                               np.median(np.diff(full_time))) if step > 1 else sigma_x
        threshold, guard = 5.0 * sigma_w, 2
        notes.append(f"run '{run.label or 0}': no position column; position integrated from the "
                     f"velocity (its unknown smoothing leaves the uncertainties about 2x "
                     f"optimistic)")
    # Orientation: in free motion the cart accelerates toward the bumper, and free motion is
    # most of the moving samples, so the median change of velocity there points to the bumper.
    moving = np.abs(w_raw) > threshold
    steps = np.diff(w_raw)[moving[:-1] & moving[1:]]
    if steps.size < 3:
        notes.append(f"run '{run.label or 0}': the cart hardly moves; no impacts")
        return empty
    orientation = 1.0 if np.median(steps) >= 0 else -1.0
    # That vote is weak where contacts are long: a soft bumper's contact steps (against the
    # bumper) can be as many as the free steps, whose sign the noise also flips (a cart at
    # 50 Hz: g·Δt ≈ σ of a step). A vote within 3σ of a coin's (binomial) is then settled by
    # the rest: a cart (or ball) ends at rest against the bumper, on the side of the moving
    # samples it bounced toward; with no clear rest the vote stands.
    toward_votes = int(np.sum(steps > 0))
    if abs(toward_votes - 0.5 * steps.size) <= 1.5 * np.sqrt(steps.size) and \
            "position" in run.columns:
        still_from = _rest_start(x, sigma_x)
        moved_x = x[:still_from][moving[:still_from]]
        if n - still_from >= 10 and moved_x.size >= 3:
            side = float(np.median(x[still_from:]) - np.median(moved_x))
            if abs(side) > 4.0 * sigma_x:
                rest_orientation = 1.0 if side > 0 else -1.0
                if rest_orientation != orientation:
                    notes.append(f"run '{run.label or 0}': direction of the bumper from the "
                                 f"final rest ({toward_votes} of {steps.size} velocity steps "
                                 f"while moving point the other way: long contacts)")
                orientation = rest_orientation
    w, s = orientation * w_raw, orientation * x  # both grow toward the bumper
    # Toward (+1), away (−1) or neither (0, within noise: apex, rest) at each sample.
    # The first and last central differences are one-sided, with twice the noise.
    band = np.full(n, threshold)
    if "position" in run.columns:
        band[[0, -1]] *= 2.0
    state = np.where(w > band, 1, np.where(w < -band, -1, 0)).astype(np.int8)
    starts, ends, values = _runs_of(state)
    lengths = ends - starts + 1
    count = starts.size
    padded_values = np.concatenate([values, [0, 0]])
    padded_lengths = np.concatenate([lengths, [0, 0]])
    i = np.arange(count)
    # A reversal at the bumper: moving toward it, then away, with at most a couple of samples
    # in between (the contact smears the velocity). Every reversal ends a flight; an impact is
    # reported only where >= 2 samples move toward and >= 2 away: rest noise cannot fake that,
    # as it would need four samples beyond 4σ with the right signs in a row. Reversals at the
    # top of the incline go the other way (away, then toward) and are flights' apexes.
    max_gap = 2 + guard
    direct = padded_values[i + 1] == -1
    bridged = ((padded_values[i + 1] == 0) & (padded_lengths[i + 1] <= max_gap)
               & (padded_values[i + 2] == -1))
    reversal = (padded_values[i] == 1) & (direct | bridged)
    away_of = np.where(direct, i + 1, i + 2)
    resolved = reversal & (padded_lengths[i] >= 2) & (padded_lengths[np.minimum(away_of, count + 1)]
                                                      >= 2)
    if not resolved.any():
        notes.append(f"run '{run.label or 0}': no velocity reversal at the bumper")
        return empty
    # Reversals up to the last resolved one cut the record into flights, and so do later ones
    # while the cart still leaves the bumper by more than the noise (short flights of the
    # last bounces: their velocity exceeds the threshold on a sample or two only). Once the
    # position stays within 4σ of where the record ends, the cart rests and a reversal there
    # would be noise.
    if "position" in run.columns:
        resting_from = _rest_start(s, sigma_x)
    else:
        resting_from = 0
    # Before the first resolved reversal a train has no slower contact (bounces only lose
    # speed): an unresolved reversal there is the noise of a cart held still before its
    # release (a sample beyond the threshold each way), unless the record starts with it
    # (a record begun just before a contact).
    held_noise = reversal & ~resolved & (i < i[resolved][0]) & (i > 0)
    if held_noise.any():
        notes.append(f"run '{run.label or 0}': {int(held_noise.sum())} reversal(s) of the "
                     f"velocity within the noise before the first clear impact left out (the "
                     f"cart still before its release)")
    keep = reversal & ~held_noise & ((i <= i[resolved][-1])
                                     | (ends[np.minimum(i + 1, count - 1)] < resting_from))
    toward_runs, away_runs = i[keep], away_of[keep]
    is_impact = resolved[keep]
    real_reversal = np.ones(is_impact.size, dtype=bool)  # False: a contact put in below
    impacts = toward_runs.size
    # The contact starts where the velocity toward the bumper peaks (free motion speeds it up,
    # the bumper slows it) and ends where the velocity away from it peaks: samples between,
    # plus a guard for the derivative's reach, are not free motion.
    # The peaks are looked for over the whole motion toward (away from) the bumper, through
    # dips of the velocity into the noise band: a slow contact's velocity away may dip below
    # the threshold before it peaks, and the flight would otherwise start inside the contact.
    bridged_starts, bridged_ends, _ = _runs_of(
        _bridge_gaps(state, starts, ends, values, max_gap))
    whole = np.searchsorted(bridged_starts, starts, side="right") - 1  # original -> bridged
    peaks = _first_extreme(w, bridged_starts, bridged_ends, "max")[whole[toward_runs]]
    troughs = _first_extreme(w, bridged_starts, bridged_ends, "min")[whole[away_runs]]
    # A motion toward the bumper after the final rest began is noise (a sample of the resting
    # cart beyond the threshold), not a last small bounce: ending the last flight there
    # would take the rest for flight and leave no resting tail to place the bumper by.
    moving_until = resting_from if "position" in run.columns else n
    later_toward = np.flatnonzero((values == 1) & (i > away_runs[-1]) & (starts < moving_until))
    if later_toward.size:  # the flight after the last resolved impact ends at the next contact
        last_end = _first_extreme(w, starts, ends, "max")[later_toward[0]] - guard - 1
    else:
        last_end = ends[away_runs[-1]]
    # Free flight is symmetric about its apex: it ends no later than the apex mirrored about
    # the contact end. Where that falls well before the next reversal, a contact showed no
    # clear reversal in between (a slow one, its speed within the noise): an unreported
    # contact is put there, so that the next impact gets its own incoming flight.
    rising = np.flatnonzero(w >= 0)

    def mirror(troughs):
        apex = (rising[np.minimum(np.searchsorted(rising, troughs), rising.size - 1)]
                if rising.size else np.full(troughs.size, n - 1))
        apex = np.where(apex >= troughs, apex, n - 1)
        return 2 * apex - troughs - guard - 1

    mirrored = mirror(troughs)
    # The apex is where the noisy velocity first turns toward the bumper: uncertain by about
    # σ_v/(g·Δt) samples (g·Δt, the velocity change per sample, is the median step in motion).
    apex_noise = sigma_w / max(abs(float(np.median(steps))), 1e-12)
    missed = np.flatnonzero((peaks[1:] - guard - 1) - mirrored[:-1] > 3.0 + 4.0 * apex_noise)
    if missed.size:
        unseen_peaks = mirrored[missed] + guard + 1
        peaks = np.insert(peaks, missed + 1, unseen_peaks)
        troughs = np.insert(troughs, missed + 1, unseen_peaks + 2)
        is_impact = np.insert(is_impact, missed + 1, False)
        real_reversal = np.insert(real_reversal, missed + 1, False)
        impacts = peaks.size
        mirrored = mirror(troughs)
    # The release: the first sample moving toward the bumper beyond the noise may still be
    # the held cart's (its central difference reaches a sample after the release).
    segment_lo = np.concatenate([[starts[toward_runs[0]] + guard], troughs + guard + 1])
    segment_hi = np.concatenate([peaks - guard - 1, [last_end]])
    segment_hi[1:] = np.minimum(segment_hi[1:], mirrored)
    index = np.arange(n)
    segment = np.searchsorted(segment_lo, index, side="right") - 1
    inside = (segment >= 0) & (index <= segment_hi[np.clip(segment, 0, None)])
    segment = np.where(inside, segment, -1)
    # The fits use every sample: each carries its block's flight label (samples after the
    # last whole block, none).
    full_s = orientation * full_x
    full_index = np.arange(full_n)
    full_segment = np.where(full_index < n * step,
                            segment[np.minimum(full_index // step, n - 1)], -1)

    label = run.label or 0

    def fit(labels, apex=None, release=None):
        """Least squares over the samples with a flight label (>= 2 per flight).

        Each flight is s(τ) = c + b·τ + a·τ²/2 about a reference time; `apex` (s, per flight)
        makes the reference the flight's apex and gives the leg before it (away from the
        bumper) and the leg after it (toward it) accelerations of their own, common to all
        flights (rolling friction adds to the incline's pull going up and subtracts from it
        going down [5]_); position and velocity stay continuous at the apex. Without `apex`,
        one acceleration for both legs. With `release` (s, the time the cart is let go) the
        first flight is a cart held still, then let go: its samples before the reference
        (`release`, or its apex with `apex`) are the held position c_0, those after it
        c_0 + b_0·τ + a·τ²/2. One pass of 5σ outlier rejection. Returns a dict of the fit;
        ``theta`` is always (a_away, a_toward, c_0, b_0, c_1, b_1, ...).
        """
        def solve(selected):
            counts = np.bincount(labels[selected], minlength=impacts + 1)
            usable = counts >= 2
            rows = np.flatnonzero(selected & usable[np.clip(labels, 0, None)])
            used = np.flatnonzero(usable)
            column = np.full(impacts + 1, -1)
            column[used] = np.arange(used.size)
            seg = labels[rows]
            reference = (np.bincount(seg, weights=full_time[rows], minlength=impacts + 1)
                         / np.maximum(counts, 1))
            if apex is not None:
                reference = np.where(np.isfinite(apex), apex, reference)
            if release is not None and (apex is None or not np.isfinite(apex[0])):
                reference[0] = release
            tau = full_time[rows] - reference[seg]
            toward = tau >= 0
            # Samples of the cart still held: no velocity, no acceleration, at c_0.
            moving = (seg != 0) | toward if release is not None else np.ones(rows.size, bool)
            # Two accelerations only where both legs are sampled well enough to tell them apart.
            split = apex is not None and min(int(toward.sum()), int((~toward & moving).sum())) >= 3
            n_acc = 2 if split else 1
            design = np.zeros((rows.size, n_acc + 2 * used.size))
            if split:
                design[:, 0] = np.where(toward | ~moving, 0.0, 0.5 * tau ** 2)
                design[:, 1] = np.where(toward, 0.5 * tau ** 2, 0.0)
            else:
                design[:, 0] = np.where(moving, 0.5 * tau ** 2, 0.0)
            design[np.arange(rows.size), n_acc + 2 * column[seg]] = 1.0
            design[np.arange(rows.size), n_acc + 1 + 2 * column[seg]] = np.where(moving, tau, 0.0)
            # Full parameters (a_away, a_toward, c, b, ...) from the fitted ones.
            expand = np.zeros((2 + 2 * used.size, design.shape[1]))
            expand[0, 0] = 1.0
            expand[1, 1 if split else 0] = 1.0
            expand[2:, n_acc:] = np.eye(2 * used.size)
            # Normal equations through the sparse design (at most three entries a row: the
            # flights' columns are disjoint), far cheaper than a dense least-squares solve
            # when a long record holds dozens of flights.
            sparse = csr_matrix(design)
            gram = (sparse.T @ sparse).toarray()
            try:  # Cholesky: the Gram matrix of a design of full column rank
                inverse = cho_solve(cho_factor(gram, check_finite=False),
                                    np.eye(gram.shape[0]), check_finite=False)
            except LinAlgError:  # rank-deficient (a degenerate flight): least norm
                inverse = np.linalg.pinv(gram)
            fitted = inverse @ (sparse.T @ full_s[rows]) if rows.size else np.zeros(design.shape[1])
            return dict(rows=rows, usable=usable, column=column, reference=reference,
                        design=design, inverse=inverse, expand=expand, split=split,
                        theta=expand @ fitted, residual=full_s[rows] - design @ fitted)

        result = solve(labels >= 0)
        if result["rows"].size == 0:
            return None
        # A sample 5σ off its flight's parabola is not free motion. Near a flight's end such a
        # sample means the flight ran into a contact that showed no clear reversal: the samples
        # after it belong to the next flight, so the flight is cut there (likewise at its
        # start).
        outliers = np.zeros(full_n, dtype=bool)
        outliers[result["rows"]] = np.abs(result["residual"]) > 5.0 * full_sigma_x
        if outliers.any():
            flight = np.clip(labels, 0, None)
            middle = (np.bincount(labels[labels >= 0], weights=full_index[labels >= 0],
                                  minlength=impacts + 1)
                      / np.maximum(np.bincount(labels[labels >= 0], minlength=impacts + 1), 1))
            late = outliers & (full_index > middle[flight])
            early = outliers & (full_index < middle[flight])
            cut_hi = np.full(impacts + 1, full_n)
            cut_lo = np.full(impacts + 1, -1)
            np.minimum.at(cut_hi, flight[late], full_index[late])
            np.maximum.at(cut_lo, flight[early], full_index[early])
            selected = ((labels >= 0) & ~outliers & (full_index < cut_hi[flight])
                        & (full_index > cut_lo[flight]))
            outliers = (labels >= 0) & ~selected
            result = solve(selected)
            if not result["usable"].any():
                return None  # every flight cut below two samples: nothing left to fit
        rows, design, residual = result["rows"], result["design"], result["residual"]
        dof = rows.size - design.shape[1]
        result["variance"] = float(residual @ residual / dof) if dof >= 3 else full_sigma_x ** 2
        # Correlated noise (a vendor's smoothing, an integrated velocity) makes s²(AᵀA)⁻¹ too
        # small: scale it by the long-run variance ratio 1 + 2Σρ_k of the residuals, lags 1-3
        # within a flight [6]_ (≈ 1 for white noise).
        seg = labels[rows]
        ratio = 1.0
        for lag in (1, 2, 3):  # loop over three lags
            same = (seg[lag:] == seg[:-lag]) & (rows[lag:] - rows[:-lag] == lag)
            if same.sum() > 10 and residual @ residual > 0:
                ratio += 2.0 * float(np.mean(residual[lag:][same] * residual[:-lag][same])
                                     / np.mean(residual ** 2))
        expand = result["expand"]
        result["scale"] = max(ratio, 1.0) * result["variance"]
        result["covariance"] = result["scale"] * expand @ result["inverse"] @ expand.T
        result["outliers"] = int(outliers.sum())
        result["samples"] = np.bincount(seg, minlength=impacts + 1)
        result["first"] = np.full(impacts + 1, np.nan)
        result["last"] = np.full(impacts + 1, np.nan)
        np.fmin.at(result["first"], seg, full_time[rows])
        np.fmax.at(result["last"], seg, full_time[rows])
        return result

    def apexes(result):
        """Time (s) of each flight's apex, where its fitted velocity is zero (NaN if unfitted).

        The velocity b + a·τ about the reference is zero before it on the leg away from the
        bumper (b > 0) and after it on the leg toward it (b < 0).
        """
        theta, usable = result["theta"], result["usable"]
        col = np.clip(result["column"], 0, None)
        b = theta[3 + 2 * col]
        with np.errstate(divide="ignore", invalid="ignore"):
            shift = np.where(b > 0, -b / theta[0], -b / theta[1])
        return np.where(usable, result["reference"] + shift, np.nan)

    def edge_parabola(result, segments, edge_times):
        """(ok, a, c, b, cov) of each segment's leg at an edge time, cov of (a, c, b).

        The leg is the one the edge time falls on: toward the bumper after the apex (the
        reference of a two-leg fit), away from it before.
        """
        ok, a, c, b, blocks, jac = edge_jacobian(result, segments, edge_times)
        cov = result["covariance"][blocks[:, :, None], blocks[:, None, :]]
        return ok, a, c, b, jac @ cov @ np.swapaxes(jac, 1, 2)

    def edge_jacobian(result, segments, edge_times):
        """(ok, a, c, b, blocks, jac) of each segment's leg at an edge time: `blocks` the
        indices in theta of (a_leg, c, b) and `jac` ∂(a, c, b at the edge)/∂(those)."""
        usable, column, theta = result["usable"], result["column"], result["theta"]
        ok = usable[segments]
        col = np.clip(column[segments], 0, None)
        delta = edge_times - result["reference"][segments]
        leg = np.where(delta >= 0, 1, 0)
        a = theta[leg]
        c0, b0 = theta[2 + 2 * col], theta[3 + 2 * col]
        c = c0 + b0 * delta + 0.5 * a * delta ** 2
        b = b0 + a * delta
        blocks = np.stack([leg, 2 + 2 * col, 3 + 2 * col], axis=-1)
        jac = np.zeros((segments.size, 3, 3))
        jac[:, 0, 0] = 1.0
        jac[:, 1, 0], jac[:, 1, 1], jac[:, 1, 2] = 0.5 * delta ** 2, 1.0, delta
        jac[:, 2, 0], jac[:, 2, 2] = delta, 1.0
        return ok, a, c, b, blocks, jac

    def speed_errors(result, bumper, var_bumper):
        """The error structure of each impact's measured speeds (see _shared_components).

        Returns (shared_in, shared_out, own_in, own_out, pair): the shifts (m/s) of the impact
        and rebound speeds per +1σ of the run's shared errors, shape (impacts,
        SHARED_ERRORS) (the two leg accelerations, one component and a zero where the legs
        share one, then the bumper position); the 1σ of each speed's own error; and the
        covariance (m²/s²) of the own errors of impact k's rebound speed and impact k + 1's
        impact speed, measured on one flight (NaN for the last impact).
        """
        k = np.arange(impacts)
        expand = result["expand"]
        n_acc = expand.shape[1] - (expand.shape[0] - 2)
        rows, measured = [], []
        for segments, edges in ((k, result["last"][k]), (k + 1, result["first"][k + 1])):
            ok, a, c, b, blocks, jac = edge_jacobian(result, segments, edges)
            measured.append(ok)
            grad, slope = _speed_gradient(a, c, b, bumper)
            row = np.zeros((impacts, expand.shape[0]))
            np.add.at(row, (k[:, None], blocks), np.einsum("ki,kij->kj", grad, jac))
            rows.append((np.where(ok[:, None], row, 0.0), np.where(ok, slope, 0.0)))
        gradient = np.concatenate([rows[0][0], rows[1][0]]) @ expand
        slope = np.concatenate([rows[0][1], rows[1][1]])
        components, rest = _shared_components(gradient, result["scale"] * result["inverse"],
                                              np.arange(n_acc), slope, np.sqrt(var_bumper))
        if n_acc == 1:  # one acceleration for both legs: no second component
            components = np.insert(components, 1, 0.0, axis=1)
        measured = np.concatenate(measured)
        components[~measured] = np.nan
        own = np.where(measured, np.sqrt(np.maximum(np.diag(rest), 0.0)), np.nan)
        pair = np.append(rest[impacts + k[:-1], k[1:]], np.nan)
        return components[:impacts], components[impacts:], own[:impacts], own[impacts:], pair

    def crossings(result, bumper, var_bumper):
        """Contact start (incoming parabola reaches the bumper) and end (outgoing leaves it)."""
        k = np.arange(impacts)
        te_in, te_out = result["last"][k], result["first"][k + 1]
        in_ok, a_in, c_in, b_in, cov_in = edge_parabola(result, k, te_in)
        out_ok, a_out, c_out, b_out, cov_out = edge_parabola(result, k + 1, te_out)
        tau_in, v_in, sd_t_in, sd_v_in = _crossing(a_in, c_in, b_in, cov_in, bumper, var_bumper,
                                                   incoming=True)
        tau_out, v_out, sd_t_out, sd_v_out = _crossing(a_out, c_out, b_out, cov_out, bumper,
                                                       var_bumper, incoming=False)
        return dict(t_in=np.where(in_ok, te_in + tau_in, np.nan),
                    t_out=np.where(out_ok, te_out + tau_out, np.nan),
                    v_in=np.where(in_ok, v_in, np.nan), v_out=np.where(out_ok, v_out, np.nan),
                    sd_t_in=sd_t_in, sd_t_out=sd_t_out, sd_v_in=np.where(in_ok, sd_v_in, np.nan),
                    sd_v_out=np.where(out_ok, sd_v_out, np.nan))

    def meeting_points(result):
        """Where each impact's incoming and outgoing parabolas meet (impacts with both fitted).

        Returns the positions s* (m), v_in·v_out/(v_in + v_out) there (m/s) and the positions'
        covariance (m²), by linear propagation of the fit's covariance: with s_in, s_out the
        parabolas' errors at the meeting time, δs* = (v_out·δs_in + v_in·δs_out)/(v_in +
        v_out) (implicit differentiation of s_in = s_out). Consecutive impacts share a flight
        and all share the leg accelerations: the covariance is not diagonal.
        """
        k = np.arange(impacts)
        te_in, te_out = result["last"][k], result["first"][k + 1]
        in_ok, a_in, c_in, b_in, blocks_in, jac_in = edge_jacobian(result, k, te_in)
        out_ok, a_out, c_out, b_out, blocks_out, jac_out = edge_jacobian(result, k + 1, te_out)
        # s_in(u) − s_out(u) = A·u² + B·u + C with u the time after te_in: the root between the
        # two edges (the one nearer their middle); linear when the legs share the acceleration.
        gap = te_out - te_in
        quadratic = 0.5 * (a_in - a_out)
        linear = b_in - b_out + a_out * gap
        const = c_in - c_out + b_out * gap - 0.5 * a_out * gap ** 2
        with np.errstate(divide="ignore", invalid="ignore"):
            root = np.sqrt(linear ** 2 - 4.0 * quadratic * const)
            candidates = np.stack([(-linear + root) / (2.0 * quadratic),
                                   (-linear - root) / (2.0 * quadratic)])
            nearest = candidates[np.argmin(np.abs(np.nan_to_num(candidates - 0.5 * gap,
                                                                nan=np.inf)), axis=0),
                                 np.arange(impacts)]
            meet = np.where(np.abs(quadratic * gap) < 1e-9 * np.abs(linear) + 1e-300,
                            -const / linear, nearest)
            speed_in = b_in + a_in * meet
            speed_out = -(b_out + a_out * (meet - gap))  # moving away: s falls
            factor = speed_in * speed_out / (speed_in + speed_out)
            share_in, share_out = (speed_out / (speed_in + speed_out),
                                   speed_in / (speed_in + speed_out))
        used = in_ok & out_ok & np.isfinite(meet) & is_impact
        rows = np.zeros((impacts, result["covariance"].shape[0]))
        for blocks, jac, u, share in ((blocks_in, jac_in, meet, share_in),
                                      (blocks_out, jac_out, meet - gap, share_out)):  # 2 legs
            with np.errstate(all="ignore"):  # impacts not used: anything, set to 0 below
                along = np.stack([0.5 * u ** 2, np.ones_like(u), u], axis=-1)  # ∂s/∂(a, c, b)
                row = share[:, None] * np.einsum("ki,kij->kj", along, jac)
            np.add.at(rows, (k[:, None], blocks), np.where(np.isfinite(row), row, 0.0))
        rows = rows[used]
        position = (c_in + b_in * meet + 0.5 * a_in * meet ** 2)[used]
        return position, factor[used], rows @ result["covariance"] @ rows.T

    def meeting_bumper(result):
        """Median position where each impact's incoming and outgoing parabolas meet."""
        meets = meeting_points(result)[0]
        if meets.size == 0:
            return None, None
        spread = float(np.std(meets)) ** 2 / meets.size if meets.size > 1 else result["variance"]
        return float(np.median(meets)), spread

    def fit_legs(labels, release=None):
        """The flights' fit with one acceleration, then with each leg's own about the apex
        (twice, the second about the apexes the first found); `release` as in fit."""
        common = fit(labels, release=release)
        if common is None:
            return None
        result = common
        for _ in range(2):  # the apex moves by a fraction of a sample at most
            legs = fit(labels, apex=apexes(result), release=release)
            if legs is None or not legs["split"]:
                return result
            result = legs
        return result

    first = fit_legs(full_segment)
    if first is None:
        notes.append(f"run '{label}': no free motion between the impacts to fit")
        return empty
    # Bumper position: given, or where the cart rests after the last impact, or (no rest)
    # where the incoming and outgoing parabolas of each impact meet.
    source = "meet"
    if bumper_position is not None:
        bumper, var_bumper, source = orientation * float(bumper_position), 0.0, "given"
        notes.append(f"run '{label}': bumper position given: {bumper_position:g} m")
    else:
        # The rest is the final stretch in which the position stays within 4σ of where the
        # record ends: small bounces before it leave the bumper by more than the noise even
        # when their speeds are too small to register. Only its second half is used, as the
        # smallest bounces (within the noise) come first. A position integrated from the
        # velocity drifts; there the stretch is the final one with no velocity beyond the
        # threshold, single-sample excursions (the one-sided derivative at the end doubles
        # the noise) not counting as motion.
        # Found on the detection blocks: a 4σ excursion of one sample among the many of a
        # fast record's tail is noise, not motion.
        if "position" in run.columns:
            rest_start = _rest_start(s, sigma_x)
        else:
            calm = np.where(np.repeat(lengths == 1, lengths), 0, state)
            calm_starts, _, calm_values = _runs_of(calm)
            rest_start = calm_starts[-1] if calm_values[-1] == 0 else n
        rest_start = step * max(rest_start, last_end + guard + 1)
        tail = full_index >= rest_start + (full_n - rest_start) // 2
        # The rest is at the bumper if it is no farther from it than the flights come: than
        # the median over flights of each one's sample nearest the bumper (a median, as a
        # flight of the first pass may hold a contact's samples), less the noise of the
        # largest of N samples, about σ·√(2·ln N) (extreme-value asymptotics), and 3σ. On
        # detection blocks the first and last of each flight may straddle a contact: only the
        # flights' inner blocks are compared.
        if step == 1:
            compared, owner = s[first["rows"]], full_segment[first["rows"]]
        else:
            inner = ((segment >= 0) & (np.roll(segment, 1) == segment)
                     & (np.roll(segment, -1) == segment))
            inner = inner if inner.any() else segment >= 0
            compared, owner = s[inner], segment[inner]
        nearest = np.full(impacts + 1, -np.inf)
        np.maximum.at(nearest, owner, compared)
        flights_reach = np.median(nearest[np.isfinite(nearest)])
        per_flight = compared.size / max(np.isfinite(nearest).sum(), 1)
        margin = (3.0 + np.sqrt(2.0 * np.log(max(per_flight, 2.0)))) * sigma_x
        if tail.sum() >= 5 and np.median(full_s[tail]) > flights_reach - margin:
            # A tail may still hold bounces within the noise (a very elastic ball's last
            # bounces go on for seconds), which place it short of the bumper: it is checked
            # against where the impacts' parabolas meet, at zero speed (see _floor_choice).
            rest = float(np.median(full_s[tail]))
            var_rest = (_MEDIAN_EFFICIENCY * full_sigma_x) ** 2 / tail.sum()
            bumper, var_bumper, source, _ = _floor_choice(
                rest, var_rest, _zero_speed_meeting(*meeting_points(first)))
        else:
            bumper, var_bumper = meeting_bumper(first)
            if bumper is None:
                notes.append(f"run '{label}': no resting tail and no impact with free motion on "
                             f"both sides: bumper position unknown")
                return empty
    # Second pass. The first cut the flights where the noisy velocity peaked, which favours
    # samples whose noise made it peak: a small selection bias at the flight ends. Now each
    # flight runs from the fitted end of the previous contact (or the fitted release, the
    # descent's vertex) to the fitted start of the next contact, or at the latest to the
    # fitted apex mirrored about the contact end (scaled by √(a_away/a_toward): the leg
    # toward the bumper lasts longer when friction slows it).
    cross = crossings(first, bumper, var_bumper)
    vertex = apexes(first)
    with np.errstate(divide="ignore", invalid="ignore"):
        legs_ratio = np.sqrt(first["theta"][0] / first["theta"][1])
    legs_ratio = legs_ratio if np.isfinite(legs_ratio) and legs_ratio > 0 else 1.0
    lo_time = np.concatenate([[vertex[0]], cross["t_out"]])
    hi_time = np.concatenate([cross["t_in"], [np.inf]])
    mirrored_time = np.concatenate([[np.inf], vertex[1:] + legs_ratio * (vertex[1:]
                                                                          - cross["t_out"])])
    hi_time = np.fmin(hi_time, mirrored_time)
    # No cut moves past the samples where the velocity turned (the contact lies between
    # them); where a fit is missing, the cut is there, or the first pass's mirrored apex. A
    # flight of a few samples then keeps the samples next to its contacts, which the first
    # pass's guard left out. The turn is where the velocity changes sign inside the contact,
    # not where it peaks beside it: the peak is chosen by the noise of the samples next to
    # the contact (a last free sample read short of the bumper makes the next difference
    # peak), and a cut there would keep those samples more often when they read short, so
    # impacts would be timed late and slow.
    # Without a position column (integrated from a vendor's smoothed velocity) the samples
    # next to a contact are smeared: no cut moves more than a sample past the first pass's.
    reach = (guard + 1) * dt if "position" in run.columns else dt
    release = None  # the time the cart is let go, where it is seen held before
    turn_lo = np.fmax(
        block_first[np.clip(np.concatenate([[segment_lo[0]], troughs]), 0, n - 1)],
        block_first[np.clip(segment_lo, 0, n - 1)] - reach) - 1e-9
    turn_hi = np.fmin(block_last[np.clip(np.concatenate([peaks, [segment_hi[-1]]]), 0, n - 1)],
                      block_last[np.clip(segment_hi, 0, n - 1)] + reach) + 1e-9
    if "position" in run.columns:
        away, toward = np.flatnonzero(w <= 0), np.flatnonzero(w >= 0)
        if away.size:  # the first sample at or after each peak not moving toward the bumper
            sign_in = away[np.minimum(np.searchsorted(away, peaks), away.size - 1)]
            turn_hi[:-1] = block_last[np.where(sign_in >= peaks, sign_in, peaks)] + 1e-9
        if toward.size:  # the last sample at or before each trough not moving away from it
            sign_out = toward[np.maximum(np.searchsorted(toward, troughs, side="right") - 1, 0)]
            turn_lo[1:] = block_first[np.where(sign_out <= troughs, sign_out, troughs)] - 1e-9
        # The release. A cut at the descent's start would keep its first samples by their own
        # noise (a sample reading nearer the bumper makes the velocity pass the threshold
        # sooner): the descent's acceleration, so every speed, would come out high. A cart
        # still from the record's start until the descent, whose fitted descent starts from
        # rest within the last ten detection blocks before it moves (not pushed), is fitted
        # over those blocks held, then let go at the fitted release (see fit). Otherwise (a
        # push, a record starting in motion) the flight starts where its velocity passed the
        # threshold.
        hold_from = max(ends[0] - 10, 0)
        if (toward_runs[0] == 1 and values[0] == 0 and np.isfinite(vertex[0])
                and block_first[hold_from] < vertex[0] < block_first[starts[1]]):
            lo_time[0] = turn_lo[0] = block_first[hold_from] - 1e-9
            release = vertex[0]
        # The last flight runs until the cart is back at rest (its apex mirrored, when fitted):
        # its return may be too slow to pass the velocity threshold.
        turn_hi[-1] = max(turn_hi[-1], block_last[np.clip(resting_from - 1, 0, n - 1)] + 1e-9)
    # Cuts at a fitted contact time (or mirrored apex), not at the turn of the velocity.
    lo_fitted = np.isfinite(lo_time) & (lo_time > turn_lo)
    hi_fitted = np.isfinite(hi_time) & (hi_time < turn_hi)
    lo_time = np.where(np.isfinite(lo_time), np.fmax(lo_time, turn_lo), turn_lo)
    hi_time = np.where(np.isfinite(hi_time), np.fmin(hi_time, turn_hi), turn_hi)
    lo_time = np.maximum.accumulate(lo_time)
    refined = np.searchsorted(lo_time, full_time, side="right") - 1
    keep = (refined >= 0) & (full_time > lo_time[np.clip(refined, 0, None)]) \
        & (full_time < hi_time[np.clip(refined, 0, None)])
    if "position" in run.columns:
        # One flight is one excursion from the bumper: where a cut spans several (bounces too
        # small to show a reversal), only its longest run of samples more than 3σ short of
        # the bumper is kept, with the sample on each side of it: whether a sample is kept
        # then never depends on its own noise (a sample kept only when it reads short of the
        # bumper would time impacts late and slow), unless it reads 3σ past the bumper.
        margin = 3.0 * np.sqrt(full_sigma_x ** 2 + var_bumper)
        off = keep & (full_s < bumper - margin)
        same = np.concatenate([[False], off[:-1] & off[1:] & (refined[:-1] == refined[1:])])
        excursion = np.where(off, np.cumsum(off & ~same), 0)
        if excursion.max() > 0:
            length = np.bincount(excursion)[1:]
            owner = refined[np.flatnonzero(off & ~same)]
            order = np.lexsort((-length, owner))
            longest = order[np.concatenate([[True], owner[order][1:] != owner[order][:-1]])]
            chosen = np.isin(excursion, longest + 1)
            same_flight = refined[1:] == refined[:-1]
            # Only where the flight is cut at a fitted contact time: a cut at the turn of the
            # velocity lies inside the contact.
            flight = np.clip(refined, 0, None)
            before = np.concatenate([chosen[1:] & same_flight, [False]]) & lo_fitted[flight]
            after = np.concatenate([[False], chosen[:-1] & same_flight]) & hi_fitted[flight]
            chosen = chosen | before | after
            keep &= chosen & (full_s < bumper + margin)
        else:
            keep &= off
    second = fit_legs(np.where(keep, refined, -1), release=release)
    result = second if second is not None else first
    if source == "meet":
        # The refit's meeting point, unless its cuts left no impact with free motion on both
        # sides: then the first pass's.
        refit_bumper, refit_var = meeting_bumper(result)
        if refit_bumper is not None:
            bumper, var_bumper = refit_bumper, refit_var
        notes.append(f"run '{label}': no resting tail; bumper position "
                     f"{orientation * bumper:.5g} m where the fitted trajectories meet (biased "
                     f"past the bumper by a long contact)")
    elif source != "given":  # the rest checked again against the refit's meeting points
        meeting = _zero_speed_meeting(*meeting_points(result))
        choice = _floor_choice(rest, var_rest, meeting)
        bumper, var_bumper = choice[:2]
        notes.append(_floor_note(label, orientation, choice, rest, var_rest, int(tail.sum()),
                                 meeting))
    cross = crossings(result, bumper, var_bumper)
    errors = speed_errors(result, bumper, var_bumper)
    resolved_count = int(is_impact.sum())
    a_away, a_toward = result["theta"][:2]
    sd_away, sd_toward = np.sqrt(np.diag(result["covariance"])[:2])
    legs.append(dict(label=str(run.label), toward=float(a_toward), toward_sd=float(sd_toward),
                     away=float(a_away), away_sd=float(sd_away), separate=bool(result["split"])))
    accelerations = (f"{a_toward:.4g} ± {sd_toward:.2g} m/s² on the legs toward the bumper and "
                     f"{a_away:.4g} ± {sd_away:.2g} m/s² on the legs away from it (the incline's "
                     f"g·sin θ less and plus rolling friction)" if result["split"] else
                     f"{a_toward:.4g} ± {sd_toward:.2g} m/s² on both legs (too few samples on "
                     f"one leg to tell them apart)")
    notes.append(f"run '{label}': free-motion acceleration toward the bumper {accelerations}, "
                 f"position noise {np.sqrt(result['variance']) * 1e3:.3g} mm, "
                 f"{resolved_count} resolved reversal(s) at the bumper "
                 f"({impacts - resolved_count} other contact(s) with fewer than two samples "
                 f"beyond the noise on a side), {result['outliers']} outlying sample(s) left out")
    # Every reversal is reported; one whose incoming or outgoing flight has fewer than two
    # free samples in the fit is flagged, timed by what it has: the incoming parabola, else the
    # outgoing one (the contact end: late by the contact), else the midpoint of the samples
    # where the velocity turned (1σ: their spacing/√12).
    k = np.arange(impacts)
    samples_in, samples_out = result["samples"][k], result["samples"][k + 1]
    short = (samples_in < 2) | (samples_out < 2)
    has_in, has_out = np.isfinite(cross["t_in"]), np.isfinite(cross["t_out"])
    turn_lo, turn_hi = time[np.clip(peaks, 0, n - 1)], time[np.clip(troughs, 0, n - 1)]
    impact_time = np.where(has_in, cross["t_in"], np.where(has_out, cross["t_out"],
                                                            0.5 * (turn_lo + turn_hi)))
    time_sd = np.where(has_in, cross["sd_t_in"], np.where(
        has_out, np.hypot(cross["sd_t_out"], dt / np.sqrt(12.0)),
        np.maximum(turn_hi - turn_lo, dt) / np.sqrt(12.0)))
    # A fitted flight whose parabola never reaches the bumper position cannot time its
    # contact (a bumper position given where the cart never is): such contacts are dropped.
    timed = has_in | ((samples_in < 2) & (has_out | (samples_out < 2)))
    if np.any(~timed):
        notes.append(f"run '{label}': {int(np.sum(~timed))} contact(s) whose fitted flight "
                     f"never reaches the bumper position dropped")
    flags = np.where(~real_reversal, "inferred", np.where(short, "few_samples", "ok"))
    speed_sd = np.fmax(cross["sd_v_in"], cross["sd_v_out"])
    speed_sd = np.where(np.isfinite(speed_sd), speed_sd, np.fmin(cross["sd_v_in"],
                                                                 cross["sd_v_out"]))
    contacts = (impact_time[timed], time_sd[timed], cross["v_in"][timed], cross["v_out"][timed],
                speed_sd[timed], flags[timed]) + tuple(part[timed] for part in errors) + (
                    k[timed],)
    # The train is built up to its last well-sampled reversal; after it the cart's smallest
    # bounces are timed better as excursions from the bumper (below), each flight fitted
    # whole, than by a reversal's one or two samples (a 2 mm error is 20 ms at 0.1 m/s).
    good = np.flatnonzero(real_reversal & ~short & timed)
    in_train = (k <= (good[-1] if good.size else -1))[timed]
    found = tuple(column[in_train] for column in contacts)
    if "position" in run.columns and found[0].size and result["split"]:
        # The last bounces: too slow for a velocity reversal beyond the noise, but each still
        # an excursion from the bumper of two samples or more.
        tail = _tail_excursions(full_time, full_s, bumper, var_bumper, full_sigma_x, result,
                                float(found[0][-1]), impacts + 1)
        if tail[0].size:
            notes.append(f"run '{label}': {tail[0].size} later contact(s) between excursions "
                         f"from the bumper of two or more samples, too slow for a velocity "
                         f"reversal beyond the noise, timed by parabolas with the fitted leg "
                         f"accelerations")
            found = tuple(np.concatenate([a, b]) for a, b in zip(found, tail))
    # Every reversal is reported all the same, flagged where short: one after the train's last
    # well-sampled reversal is put back unless a contact of the train lies within 3σ of the
    # samples where its velocity turned, which bracket the contact (the same contact, timed
    # by its excursions; a reversal timed by its outgoing flight alone is late by the contact).
    times, sigmas = found[0], found[1]
    sigma = np.hypot(contacts[1], np.max(sigmas) if sigmas.size else 0.0)
    window_lo = np.minimum(turn_lo[timed], contacts[0]) - 3.0 * sigma
    window_hi = np.maximum(turn_hi[timed], contacts[0]) + 3.0 * sigma
    represented = (np.searchsorted(times, window_hi, side="right")
                   > np.searchsorted(times, window_lo, side="left"))
    represented |= ~(k > (good[-1] if good.size else impacts))[timed]  # no train: none back
    if np.any(~represented):
        notes.append(f"run '{label}': {int(np.sum(~represented))} reversal(s) after the last "
                     f"with two free-flight samples on each side kept, flagged as the others")
        found = tuple(np.concatenate([a, b[~represented]]) for a, b in zip(found, contacts))
        order = np.argsort(found[0], kind="stable")
        found = tuple(a[order] for a in found)
    # Past the last resolved reversal the bounces shrink into the noise: the train ends where
    # an impact's timing noise exceeds a quarter of the change between successive intervals,
    # (1 − r)·interval/4 with r the median interval ratio so far, beyond which intervals
    # would no longer shrink bounce by bounce (a ratio above 1 would be a 3σ event before).
    # This is a limit on the timing, not on the samples: a short reversal timed well enough
    # stays, flagged.
    times, sigmas = found[0], found[1]
    resolved_times = impact_time[timed & real_reversal & is_impact]
    trailing = times > (resolved_times[-1] if resolved_times.size else np.inf)
    if times.size >= 4 and trailing.any():
        intervals = np.diff(times)
        ratio = float(np.median(intervals[1:][~trailing[2:]] / intervals[:-1][~trailing[2:]])) \
            if np.any(~trailing[2:]) else np.nan
        if np.isfinite(ratio) and ratio < 1.0:
            noisy = trailing[1:] & (sigmas[1:] > (1.0 - ratio) * intervals / 4.0)
            if noisy.any():
                cut = int(np.flatnonzero(noisy)[0]) + 1
                notes.append(f"run '{label}': {times.size - cut} last contact(s) left out: their "
                             f"timing noise exceeds a quarter of the change between successive "
                             f"intervals (median interval ratio {ratio:.3f}), the train ends "
                             f"there")
                found = tuple(a[:cut] for a in found)
    # A flight's own error is shared by the rebound speed before it and the impact speed
    # after it: stated only where the next contact is the one that flight ends at.
    # Stated as the correlation of those two own errors.
    origin, own_in, own_out = found[-1], found[8], found[9]
    follows = np.append(origin[1:] == origin[:-1] + 1, False)
    with np.errstate(invalid="ignore", divide="ignore"):
        correlation = np.clip(found[10] / (own_out * np.append(own_in[1:], np.nan)), -1.0, 1.0)
    found = found[:10] + (np.where(follows, correlation, np.nan),)
    final_flags = found[5]
    inferred = int(np.sum(final_flags == "inferred"))
    if inferred:
        notes.append(f"run '{label}': {inferred} contact(s) without a visible reversal (a "
                     f"flight ending well before the next reversal, its apex mirrored) flagged "
                     f"'inferred'")
    few = int(np.sum(final_flags == "few_samples"))
    if few:
        notes.append(f"run '{label}': {few} reversal(s) with fewer than two free-flight samples "
                     f"on a side flagged 'few_samples' (timed by what there is: the incoming "
                     f"flight, else the outgoing one, else the samples where the velocity "
                     f"turned)")
    return found


def _no_speed_errors(count):
    """The speed-error arrays of `count` contacts that have none stated (see
    _motion_run's speed_errors): shared components, own σ, flight pair covariance."""
    return (np.full((count, SHARED_ERRORS), np.nan), np.full((count, SHARED_ERRORS), np.nan),
            np.full(count, np.nan), np.full(count, np.nan), np.full(count, np.nan))


def _tail_excursions(time, s, bumper, var_bumper, sigma_x, fitted, after, origin=0):
    """Contacts after time `after` found as excursions of the position from the bumper.

    An excursion is a run of two or more consecutive samples more than 4σ short of the bumper
    (a resting cart's noise makes one sample in 30 000 do that, two in a row almost never).
    The first excursion after `after` is the flight that follows the last contact found; each
    later one follows a contact of its own. Each excursion is fitted with its own position and
    velocity and the run's leg accelerations (fixed), about its apex (found by iterating);
    a contact is timed where the parabola before it reaches the bumper, with speeds from
    both parabolas, as in read_motion_sensor. Excursions stop at the first of fewer than two
    samples. A contact whose neighbouring samples both stay off the bumper joins two flights
    into one excursion; one that no parabola fits (a residual beyond 5σ) is split at its
    sample nearest the bumper. Each flight is then fitted again on every sample between where
    its parabola leaves the bumper and where it meets it (twice), so that no sample is fitted
    or left out for its own noise.

    Returns arrays (time, σ_time, impact speed, rebound speed, σ_speed, flag), then the
    speeds' error structure as _motion_run's speed_errors states it (the shared components on
    the basis of the run's fit `fitted`: its leg accelerations, which every excursion's fit
    takes as fixed, and the bumper position), and each contact's `origin` + its number.
    """
    empty = (tuple(np.empty(0) for _ in range(5)) + (np.empty(0, dtype=object),)
             + _no_speed_errors(0) + (np.empty(0, dtype=int),))
    margin = 4.0 * np.sqrt(sigma_x ** 2 + var_bumper)
    off = (s < bumper - margin) & (time > after)
    starts, ends, values = _runs_of(off.astype(np.int8))
    starts, ends = starts[values == 1], ends[values == 1]
    # A single sample beyond the margin a sample or two from an excursion is its edge
    # flickering with the noise (at 100 Hz and more an edge has many samples near the margin),
    # not an excursion of its own: it is left out rather than ending the train.
    single = ends == starts
    near_before = np.concatenate([[False], (starts[1:] - ends[:-1] <= 2) & ~single[:-1]])
    near_after = np.concatenate([(starts[1:] - ends[:-1] <= 2) & ~single[1:], [False]])
    flicker = single & (near_before | near_after)
    starts, ends = starts[~flicker], ends[~flicker]
    a_away, a_toward = fitted["theta"][:2]

    def fit(starts, ends):
        """Each excursion's c, b (about its apex), their covariance and its worst residual."""
        marker = np.zeros(time.size + 1, dtype=int)
        np.add.at(marker, starts, 1)
        np.add.at(marker, ends + 1, -1)
        rows = np.flatnonzero(np.cumsum(marker)[:-1] > 0)
        member = np.searchsorted(starts, rows, side="right") - 1
        n_k = np.bincount(member).astype(float)

        def solve(apex, accelerations=(a_away, a_toward)):
            """Per excursion s − a_leg·τ²/2 = c + b·τ by least squares (closed form)."""
            tau = time[rows] - apex[member]
            y = s[rows] - 0.5 * np.where(tau >= 0, accelerations[1], accelerations[0]) * tau ** 2
            st, stt = np.bincount(member, tau), np.bincount(member, tau ** 2)
            sy, sty = np.bincount(member, y), np.bincount(member, tau * y)
            det = n_k * stt - st ** 2
            c, b = (stt * sy - st * sty) / det, (n_k * sty - st * sy) / det
            # Covariance of (c, b) for white noise of σ_x.
            return (c, b, sigma_x ** 2 * stt / det, sigma_x ** 2 * n_k / det,
                    -sigma_x ** 2 * st / det, y - c[member] - b[member] * tau)

        apex = np.bincount(member, weights=time[rows]) / n_k
        for _ in range(3):  # the apex moves by a fraction of a sample after the first pass
            c, b, *_ = solve(apex)
            apex = apex + np.where(b > 0, -b / a_away, -b / a_toward)
        *solution, residual = solve(apex)
        worst = np.zeros(starts.size)
        np.maximum.at(worst, member, np.abs(residual))
        fit.solve = solve
        return apex, solution, worst

    for attempt in range(4):  # split excursions that hold two flights (below)
        long_enough = ends - starts + 1 >= 2
        if not long_enough.any():
            return empty
        # Up to the first excursion too short to fit: later ones cannot be told from noise.
        stop = np.flatnonzero(~long_enough)
        starts, ends = starts[: stop[0] if stop.size else None], ends[: stop[0] if stop.size
                                                                       else None]
        if starts.size < 2:
            return empty
        apex, (c, b, var_c, var_b, cov_cb), worst = fit(starts, ends)
        # A contact whose neighbouring samples both stay 4σ off the bumper joins two flights
        # into one excursion, which no parabola fits: split it at the sample nearest the
        # bumper (the contact is next to it), leaving that sample out.
        # The last attempt splits nothing: the excursions stay those just fitted.
        joined = np.flatnonzero((worst > 5.0 * sigma_x) & (ends - starts >= 4))
        if joined.size == 0 or attempt == 3:
            break
        index = np.arange(time.size)
        inside = [(index > starts[k]) & (index < ends[k]) for k in joined]  # a few at most
        nearest = np.array([int(np.argmax(np.where(m, s, -np.inf))) for m in inside])
        starts = np.sort(np.concatenate([starts, nearest + 1]))
        ends = np.sort(np.concatenate([ends, nearest - 1]))
    # An excursion's samples are those more than 4σ short of the bumper: at its ends a sample
    # is kept only when its noise reads it short, so its parabola would come out too high
    # (the speeds at the bumper high by 0.2σ). Each flight is fitted again (twice) on every
    # sample between where its parabola leaves the bumper and where it meets it again, never
    # reaching into a neighbouring excursion: whether a sample is fitted then no longer
    # depends on its own noise.
    first_index = int(np.searchsorted(time, after, side="right"))
    for _ in range(2):
        with np.errstate(invalid="ignore", divide="ignore"):
            depth = 2.0 * (bumper - c)
            leave = apex + (-b - np.sqrt(b ** 2 + a_away * depth)) / a_away
            meet = apex + (-b + np.sqrt(b ** 2 + a_toward * depth)) / a_toward
        lo = np.concatenate([[first_index], ends[:-1] + 1])
        hi = np.concatenate([starts[1:] - 1, [time.size - 1]])
        new_starts = np.where(np.isfinite(leave), np.searchsorted(time, leave, side="right"),
                              starts)
        new_ends = np.where(np.isfinite(meet), np.searchsorted(time, meet, side="left") - 1,
                            ends)
        new_starts, new_ends = np.clip(new_starts, lo, hi), np.clip(new_ends, lo, hi)
        wide = new_ends - new_starts + 1 >= 2
        wide[1:] &= new_starts[1:] > new_ends[:-1]  # two flights never share a sample
        wide[:-1] &= new_starts[1:] > new_ends[:-1]
        starts, ends = np.where(wide, new_starts, starts), np.where(wide, new_ends, ends)
        apex, (c, b, var_c, var_b, cov_cb), worst = fit(starts, ends)
    count = starts.size
    cov_a = np.diag(fitted["covariance"])[:2]

    def edge(k, times, toward):
        """(a, c, b, cov of (a, c, b)) of excursion k's leg at the edge times."""
        delta = times - apex[k]
        a = a_toward if toward else a_away
        ce = c[k] + b[k] * delta + 0.5 * a * delta ** 2
        be = b[k] + a * delta
        jac = np.zeros((k.size, 3, 3))
        jac[:, 0, 0] = 1.0
        jac[:, 1, 0], jac[:, 1, 1], jac[:, 1, 2] = 0.5 * delta ** 2, 1.0, delta
        jac[:, 2, 0], jac[:, 2, 2] = delta, 1.0
        cov = np.zeros((k.size, 3, 3))
        cov[:, 0, 0] = cov_a[1] if toward else cov_a[0]
        cov[:, 1, 1], cov[:, 2, 2] = var_c[k], var_b[k]
        cov[:, 1, 2] = cov[:, 2, 1] = cov_cb[k]
        return a, ce, be, jac @ cov @ np.swapaxes(jac, 1, 2)

    k_in = np.arange(count - 1)
    a_in, c_in, b_in, cov_in = edge(k_in, time[ends[:-1]], toward=True)
    a_out, c_out, b_out, cov_out = edge(k_in + 1, time[starts[1:]], toward=False)
    tau_in, v_in, sd_t, sd_v_in = _crossing(a_in, c_in, b_in, cov_in, bumper, var_bumper,
                                            incoming=True)
    _, v_out, _, sd_v_out = _crossing(a_out, c_out, b_out, cov_out, bumper, var_bumper,
                                      incoming=False)
    impact = time[ends[:-1]] + tau_in
    ok = np.isfinite(impact) & (impact < time[starts[1:]])
    if not ok.all():  # a parabola that misses the bumper ends the tail there
        last = np.flatnonzero(~ok)[0]
        ok = np.arange(ok.size) < last
    # The speeds' errors. Every excursion's fit takes the run's leg accelerations as fixed:
    # its speeds follow them directly and through the refitted c and b (linear in them, so
    # a central difference is exact up to rounding); the rest is each excursion's own (c,
    # b), shared by the rebound speed before it and the impact speed after it.
    solve = fit.solve

    def contact_speeds(accelerations):
        c_a, b_a, *_ = solve(apex, accelerations)
        out = []
        for k, edges, leg in ((k_in, time[ends[:-1]], 1), (k_in + 1, time[starts[1:]], 0)):
            delta = edges - apex[k]
            a = accelerations[leg]
            ce = c_a[k] + b_a[k] * delta + 0.5 * a * delta ** 2
            be = b_a[k] + a * delta
            with np.errstate(invalid="ignore"):
                out.append(np.sqrt(be ** 2 + 2.0 * a * (bumper - ce)))
        return np.concatenate(out)

    accelerations = np.array([a_away, a_toward])
    total = np.zeros((2 * k_in.size, 2))
    with np.errstate(all="ignore"):
        for j in range(2):  # loop over the two leg accelerations
            step = np.zeros(2)
            step[j] = 1e-6 * np.max(np.abs(accelerations))
            total[:, j] = ((contact_speeds(accelerations + step)
                            - contact_speeds(accelerations - step)) / (2.0 * step[j]))
    try:
        factor = np.linalg.cholesky(fitted["scale"] * fitted["inverse"][:2, :2])
    except np.linalg.LinAlgError:  # a degenerate fit: nothing stated
        factor = np.full((2, 2), np.nan)
    speeds = np.concatenate([v_in, v_out])
    with np.errstate(all="ignore"):
        components = np.column_stack([total @ factor,
                                      np.repeat([a_toward, a_away], k_in.size) / speeds
                                      * np.sqrt(var_bumper)])
        # ∂v/∂c and ∂v/∂b of each excursion's own (c, b) about its apex.
        delta = np.concatenate([time[ends[:-1]] - apex[k_in], time[starts[1:]] - apex[k_in + 1]])
        b_edge = np.concatenate([b_in, b_out])
        acc = np.concatenate([np.full(k_in.size, a_toward), np.full(k_in.size, a_away)])
        g_c = -acc / speeds
        g_b = (b_edge - acc * delta) / speeds
        owner = np.concatenate([k_in, k_in + 1])
        own_var = (g_c ** 2 * var_c[owner] + 2.0 * g_c * g_b * cov_cb[owner]
                   + g_b ** 2 * var_b[owner])
        half = k_in.size
        # Impact j's rebound (excursion j + 1 at its start) and impact j + 1's impact speed
        # (excursion j + 1 at its end).
        out_c, out_b, in_c, in_b = g_c[half:-1], g_b[half:-1], g_c[1:half], g_b[1:half]
        shared_exc = k_in[1:]
        pair = np.append(out_c * in_c * var_c[shared_exc] + (out_c * in_b + out_b * in_c)
                         * cov_cb[shared_exc] + out_b * in_b * var_b[shared_exc], np.nan)
        own = np.sqrt(np.maximum(own_var, 0.0))
    return (impact[ok], sd_t[ok], v_in[ok], v_out[ok], np.fmax(sd_v_in, sd_v_out)[ok],
            np.full(int(ok.sum()), "ok", dtype=object), components[:half][ok],
            components[half:][ok], own[:half][ok], own[half:][ok], pair[ok],
            origin + k_in[ok])


def _speed_error_columns(shared_in, shared_out, own_in, own_out, correlation):
    """The impact table's columns of the speeds' error structure (MOTION_SPEED_ERROR_COLUMNS
    of :mod:`dashpot.ingest`) from the reader's arrays; NaN where a speed is not measured."""
    columns = {}
    for prefix, shared in (("impact_speed", shared_in), ("rebound_speed", shared_out)):
        for j in range(shared.shape[1]):
            columns[f"{prefix}_shared_{j + 1}"] = shared[:, j]
    columns["impact_speed_own"], columns["rebound_speed_own"] = own_in, own_out
    columns["flight_correlation"] = correlation
    return columns


def _chosen_track(path, table, runs, track):
    """The runs of the `track` asked for in a Tracker export (all runs when it has one track).

    A Tracker export of several tracks with positions without `track`, or a `track` it does
    not hold, is an InputError naming the tracks there are.
    """
    tracks = table.tracks
    available = ", ".join(f"'{name}'" for name in tracks)
    if track is None:
        # Several tracks with a time and a position (or velocity) are ambiguous; one of them
        # beside tracks without (a protractor, a tape measure) is not.
        if len(tracks) > 1 and len(runs) > 1:
            raise InputError(path, f"{table.where}Tracker export of {len(tracks)} tracks "
                                   f"({available}): choose one (read_motion_sensor(..., "
                                   f"track='{tracks[0]}')), or export that track alone")
        return runs
    if len(tracks) == 1 and track == tracks[0]:
        return runs
    chosen = [run for run in runs if run.label == track]
    if not chosen:
        held = (f"the file's tracks: {available}" if tracks else
                "the file is not a Tracker export of several tracks")
        raise InputError(path, f"{table.where}no track '{track}' to read ({held})")
    return chosen


def read_motion_sensor(path, *, bumper_position=None, track=None):
    """Impacts of a cart (or ball) from a motion-sensor or video-tracker position export.

    Parameters
    ----------
    path : str or os.PathLike
        Text table or workbook (.xlsx, .xls, .ods) with, per run, a time column and a position
        and/or velocity column in the export's words: PASCO Capstone ``Time (s) Run #1``,
        ``Position (m) Run #1``, ``Velocity (m/s) Run #1`` (and ``Acceleration`` columns, not
        used); Vernier ``Latest: Time (s)``, ``Run 1: Position (m)``, ``Latest: Velocity
        (m/s)``, ``Data Set 1:Position(m)`` and Vernier's text format (``Vernier Format 2``,
        a data set per run); Tracker's data export (a first line naming the track, ``t``,
        ``x``, ``y`` without units [7]_; several tracks in Tracker 6's layout or one below
        the other: see `track`; of several coordinates the one whose velocity spreads most,
        the one bounced along) or any ``t,y`` table. Several runs side by side. A single
        reading far off both its neighbours (a motion sensor's lost echo) is left out,
        noted. Blanks at a
        column's start or end are normal (a derivative starts a sample or two after the
        position; shorter runs end early); a blank between a column's values is an error. The
        position is read when there is one, and the velocity beside it is then not used. Units
        m/cm/mm, m/s/cm/s/mm/s, s/ms; a position without a unit is read in m.
    bumper_position : float, optional
        Position reading (m, the file's axis) at which the cart touches the bumper, if known
        from the scene, in [-20, 20] m. Otherwise estimated (see Notes).
    track : str, optional
        Name of the track to read from a Tracker export of several tracks (Tracker 6 writes
        ``#multi:``, a row with each track's name above its columns, the header ``t``, ``x``,
        ``y``, ``x``, ``y``, ... and blanks where a track has no point; or the tracks one below
        the other, each under a line with its name). Without it such a file is refused, the
        error naming its tracks, unless only one track has a position or velocity column; a
        single-track export needs none.

    Returns
    -------
    pandas.DataFrame
        Impact table of :mod:`dashpot.ingest`: ``time`` (s, the file's clock) of each contact
        start, ``impact_speed`` and ``rebound_speed`` (m/s) and their common 1σ
        ``speed_uncertainty`` (the larger of the two), ``run`` the 0-based order of the run in
        the file (``notes`` map it to the run's label; every run is returned), and ``flag``:
        "ok", "few_samples" (fewer than two free-flight samples on a side of the reversal) or
        "inferred" (a contact whose reversal the samples do not show). The speeds' errors
        are correlated, and the table states how (the columns of the speeds' correlated
        errors of :mod:`dashpot.ingest`): a run's speeds share its fitted leg accelerations
        and bumper position (``impact_speed_shared_1..3``, ``rebound_speed_shared_1..3``:
        the two accelerations' independent components, then the bumper's), and a flight's
        rebound speed and the next impact speed its parabola (``impact_speed_own``,
        ``rebound_speed_own``, ``flight_correlation``); see Notes, step 8. ``attrs
        ['accelerations']`` lists per run the free-motion accelerations toward the bumper on
        the legs toward it and away from it (m/s², with 1σ).

    Raises
    ------
    InputError
        Empty file, not a table, no time column or no position/velocity column, bad cells,
        missing/negative/non-increasing times (row named), a value missing between the values
        of the column read, duplicated rows, unknown units; motion without a bounce (no run
        with more than one reversal at the bumper); a Tracker export of several tracks without
        `track`, or a `track` the file does not hold (the error names the tracks there are).
    ValueError
        If `bumper_position` is not a finite number in [-20, 20] m.

    Notes
    -----
    A sensor sampling at 20-50 Hz has one or two points near each hit, and those are smeared
    by the contact and by the derivative. They are not used. Instead:

    0. Rate: steps 1-4 (and the resting tail of step 7) work on one reading per ~20 ms: a
       record sampled faster (100-400 Hz) is read there as means of the nearest whole number
       of consecutive samples (2 at 100 Hz, 4 at 200 Hz), whose central differences have
       noise σ_x/(√(2k)·k·Δt) rather than σ_x/(√2·Δt), and on which a soft contact's turn
       spans as many readings as at 50 Hz. The fits (steps 5-8) and the excursions below use
       every sample, cut at times, not at blocks.
    1. Velocity: central differences of the position (noise σ_v = σ_x/(√2·Δt), with σ_x
       from the third differences, which vanish for free motion [4]_, and no smaller than the
       column's resolution over √12, the resolution being the smallest change between
       consecutive readings); the vendor's own velocity column is used only when there is no
       position (then integrated for one).
    2. Orientation: the median change of velocity while moving points toward the bumper
       (free motion accelerates toward it and is most of the record). Where long contacts
       make that vote a near tie (within 3σ of a coin's), the final rest settles it: the
       cart rests against the bumper, on the side of the moving samples it bounced toward.
    3. Reversals toward → away at most two (plus guard) samples apart end the flights. One
       with at least two samples beyond ±4σ_v toward the bumper and two away is *resolved*: a
       resting cart's noise cannot produce that (four samples beyond 4σ with the right signs).
       Reversals after the last resolved one count while the position still leaves the bumper
       by more than 4σ_x (the last, short flights); reversals at the top of the incline go
       the other way and are apexes. An unresolved reversal before the first resolved one
       (not at the record's start) is the noise of the held cart and is left out, as is a
       motion toward the bumper after the final rest began.
    4. Flights, first pass: from the peak velocity away from the bumper after a contact
       (where it ended) to the peak velocity toward it before the next (where it starts),
       each peak sought over the whole motion in that direction, through dips of at most two
       (plus guard) samples into the noise band (a slow contact's velocity away dips there
       before it peaks), less a guard sample (the release's first moving sample too); and
       no later than the apex mirrored about the contact end. Where that mirror falls well
       short of the next reversal, a slow contact showed no clear reversal in between: a
       contact is put there (flagged "inferred"), so the next impact gets its own incoming
       flight.
    5. Fit: all flight samples by least squares, each flight s(τ) = c + b·τ + a·τ²/2 about its
       apex with one acceleration for the legs away from the bumper and another for the legs
       toward it, common to all flights of the run (on an incline rolling friction adds to the
       pull going up and subtracts from it going down [5]_), position and velocity continuous
       at the apex; first with a single acceleration, then twice about the apexes found. Both
       are reported; with fewer than three samples on either kind of leg, one acceleration.
       Samples 5σ off their parabola, and the rest of the flight beyond them, are left out
       (a contact the reversals missed). Covariance s²(AᵀA)⁻¹, scaled by the residuals'
       long-run variance ratio 1 + 2Σρ_k when the noise is correlated [6]_.
    6. Second pass: each flight is cut again at the *fitted* contact times (and the fitted
       release), never past the sample where the velocity changes sign inside the contact,
       and refitted. Of the samples between the cuts, a flight keeps its longest run of
       samples more than 3σ short of the bumper and the sample on either side of it (unless
       3σ past the bumper): no sample is kept or left out for its own noise, which would time
       impacts late and slow (a sample near a contact kept only when it reads short of the
       bumper; the velocity's peak next to a contact is chosen by that noise too). A cart
       still from the record's start until its descent (not pushed: the fitted descent
       starts from rest there) is fitted held over its last 0.2 s still (ten detection
       blocks), then let go at the fitted release, rather than cut where the velocity first
       passed the noise band: that cut kept the descent's first samples by their own noise,
       and every speed came out high (by 0.07σ on the paper's cart at 50 Hz).
    7. Impact time: where the incoming parabola reaches the bumper position, i.e. the start
       of contact (the convention of :func:`dashpot.bounce_sequence`); the outgoing parabola
       leaves it at the end of contact. The bumper position is the ``bumper_position``
       argument; else the median of the second half of the final stretch in which the
       position stays within 4σ of where the record ends (the cart at rest; it includes a
       soft bumper's static compression g·sin θ/ω0², which makes the times late by that
       distance over the impact speed); else the median point where incoming and outgoing
       parabolas meet (past the bumper by a long contact; noted). That tail may still hold
       bounces within the noise, which only take the object away from the bumper (a very
       elastic ball, ε ≈ 0.98, bounces for seconds after its last visible bounce): it is
       checked against the impacts' meeting points extrapolated to an instantaneous contact,
       the intercept B of meet_k = B + T·v_in·v_out/(v_in + v_out) (T the contact duration)
       by generalized least squares over the impacts [8]_, their covariance propagated from
       the fit's. Where the tail lies more than 3σ of the difference short of B, B is used;
       more than 3σ past it, the tail; between, the more precise of the two (a cart's tail
       on a soft bumper; a ball's B). The notes say which and why, with B and T.
    8. Speeds: each leg's slope at those crossings, √(b² + 2a·D) with D the distance left and
       a that leg's acceleration, so the impact speed of a bounce and the rebound speed of
       the one before are measured separately; 1σ by linear propagation of the fit covariance
       and of the bumper position's uncertainty. Every speed of a run depends on the run's
       two accelerations, so their errors are shared (a run's impact speeds correlated by
       about 0.9): each speed's total derivative with respect to them (the flights' own
       parameters following as their conditional mean does), times the Cholesky factor of
       their covariance, is stated per impact, with the bumper position's part and the
       own σ that is left; the own errors of a flight's two speeds, both about √(2a·h) of
       its apex height h, are correlated (``flight_correlation``, near 1). Speeds timed by
       the excursions below take the accelerations as fixed; their shared parts follow
       through each excursion's refit. Their stated error structure matches the scatter of
       the speeds over noise draws (tests/test_speed_errors.py).

    Every reversal is reported. One whose incoming or outgoing flight has fewer than two free
    samples in the fit is flagged "few_samples" and timed by what it has: the incoming
    parabola, else the outgoing one (the contact end), else the midpoint of the samples where
    the velocity turned (1σ: their spacing/√12); the speed it cannot measure is NaN. After the
    last reversal with two free samples on each side the excursions below time the smallest
    bounces better (each flight fitted whole); a flagged reversal there is replaced by the
    contact they find within 3σ of the samples where its velocity turned, and kept, flagged,
    where they find none (velocity-only
    records, which have no excursions, keep them all). A contact whose fitted flight never
    reaches the bumper position is left out, noted; so are the contacts past the train's end
    below.

    After the last reversal, bounces too slow to pass the velocity threshold are still found
    as excursions of the position from the bumper: runs of two or more samples more than 4σ
    short of it, each fitted with its own position and velocity and the run's two leg
    accelerations, then again on every sample between where its parabola leaves the bumper
    and where it meets it (the samples 4σ short of it alone are chosen by their noise at
    the ends, and the speeds came out high); a contact lies between consecutive excursions.
    The train ends where an impact's timing noise exceeds a quarter of the change between
    successive intervals, (1 − r)·interval/4 with r the median interval ratio: beyond it the
    intervals no longer shrink bounce by bounce within the noise. The limit is on the timing,
    not on the samples: a short reversal timed well enough stays in the train, flagged.
    """
    if bumper_position is not None:
        bumper_position = check_range("bumper_position", bumper_position,
                                      *BUMPER_POSITION_RANGE, unit="m", low_inclusive=True)
    table = _table_of_kind(path, "motion_sensor", "no position or velocity column",
                           "a motion sensor (expected e.g. 'Time (s) Run #1' and "
                           "'Position (m) Run #1'")
    _check_duplicates(path, table)
    # A Tracker track has no point on a frame nobody marked: such rows are left out of it.
    runs = _runs(path, table, {"position": (_POSITION_NAMES, "length"),
                               "velocity": (_VELOCITY_NAMES, "speed")},
                 skip_blanks=bool(table.tracks))
    if not runs:
        raise InputError(path, f"{table.where}no run has both a time column and a position or "
                               f"velocity column")
    runs = _chosen_track(path, table, runs, track)
    vendor = ("Tracker" if "Tracker" in table.variant else
              "Vernier" if any(":" in c.header for c in table.columns) else
              "PASCO" if any(re.search(r"run\s*#", c.header, re.I) for c in table.columns)
              else "unlabelled")
    notes = [f"file variant: {table.variant}; {vendor} column layout, {len(runs)} run(s): "
             + ", ".join(f"run {k} = '{r.label or '(unlabelled)'}'" for k, r in enumerate(runs))]
    skipped = sum(int(np.sum(np.diff(r.rows) - 1)) for r in runs)
    if skipped:
        notes.append(f"{skipped} frame(s) without a point inside the track left out (Tracker "
                     f"leaves a frame nobody marked blank)")
    if any(c.unit is None and c.name in _POSITION_NAMES for c in table.columns):
        notes.append("position column without a unit: read in m (Tracker writes its calibrated "
                     "world units, usually m, without naming them)")
    parts, legs = [], []
    for number, run in enumerate(runs):  # loop over runs
        before = len(legs)
        run = _without_glitches(run, notes)
        result = _motion_run(run, bumper_position, notes, legs)
        parts.append(result + (np.full(result[0].size, number),))
        if len(legs) > before:
            legs[-1] = dict(run=number, **legs[-1])
        if "column" in run.columns and len([c for c in table.columns if c.run == run.label
                                            and c.name in _POSITION_NAMES]) > 1:
            notes.append(f"run {number}: position read from column '{run.columns['column']}' "
                         f"(the coordinate bounced along: its velocity spreads most)")
    merged = [np.concatenate([p[q] for p in parts]) for q in range(12)]
    counts = [p[0].size for p in parts]
    if max(counts) == 1:
        where = " in every run" if len(runs) > 1 else ""
        raise InputError(path, f"{table.where}motion but no bounce: a single reversal at the "
                               f"bumper{where} (a cart pushed by hand, or caught after one hit); "
                               f"a bounce train needs at least two impacts")
    frame = _impact_frame(path, "motion_sensor", notes, merged[0], merged[1],
                          impact_speed=merged[2], rebound_speed=merged[3],
                          speed_uncertainty=merged[4], flag=merged[5], run=merged[11],
                          speed_errors=_speed_error_columns(*merged[6:11]))
    frame.attrs["accelerations"] = legs
    return frame
