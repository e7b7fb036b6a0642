"""The noise fit's optimizer: damped Newton steps over a batch of parameter sets at once.

Every evaluation of the noise model's likelihood is a loop over the impacts with numpy over a
batch of parameter sets, so a thousand parameter sets cost about as much as one. lmfit's scalar
minimizers evaluate one set at a time (Nelder–Mead: hundreds to thousands of calls), so the
minimization here is a damped Newton method with central-difference gradient and Hessian, all
the stencil's points of every row (train and start) in one objective call. Coordinates are
rescaled every iteration to the current standard errors, so one step size fits parameters that
differ by orders of magnitude (:func:`_newton`; the fit that uses it and its starts are in
:mod:`dashpot.fit.noise_fit`).

References
----------
.. [1] W. H. Press et al., *Numerical Recipes*, 3rd ed., Cambridge (2007), sec. 15.5
   (Newton steps damped by a multiple of the Hessian's diagonal, after Levenberg and Marquardt)
   and 5.7 (numerical derivatives).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .noise_settings import CONVERGED, FAR, SOFT_UNIT_MAX, STEP

@dataclass
class _Fits:
    """Newton fits of a batch: (trains, starts) leading axes, or (trains,) once picked."""

    params: np.ndarray
    value: np.ndarray
    covariance: np.ndarray  # of the free parameters, in natural (fitted) coordinates
    units: np.ndarray
    evaluations: int
    hessian: np.ndarray  # of −2 ln L in the free parameters, natural coordinates


def _pick(fits, rows, columns):
    return _Fits(fits.params[rows, columns], fits.value[rows, columns],
                 fits.covariance[rows, columns], fits.units[rows, columns], fits.evaluations,
                 fits.hessian[rows, columns])


def _stencil(count):
    """Offsets (points, count) of central differences: centre, ±e_i, ±e_i ± e_j."""
    unit = np.eye(count)
    rows = [np.zeros(count)] + [sign * unit[i] for i in range(count) for sign in (1, -1)]
    pairs = [(i, j) for i in range(count) for j in range(i + 1, count)]
    rows += [a * unit[i] + b * unit[j] for i, j in pairs for a, b in
             ((1, 1), (1, -1), (-1, 1), (-1, -1))]
    return STEP * np.array(rows), pairs


def _derivatives(values, count, pairs):
    """Gradient and Hessian (in the stencil's units) from the values at the stencil points."""
    centre = values[..., 0]
    plus, minus = values[..., 1:2 * count:2], values[..., 2:2 * count + 1:2]
    gradient = (plus - minus) / (2.0 * STEP)
    hessian = np.zeros(values.shape[:-1] + (count, count))
    diagonal = (plus - 2.0 * centre[..., None] + minus) / STEP ** 2
    hessian[..., range(count), range(count)] = diagonal
    if pairs:
        # The four points ±e_i ± e_j of every pair, in the stencil's order (+,+), (+,−),
        # (−,+), (−,−).
        corners = values[..., 1 + 2 * count:1 + 2 * count + 4 * len(pairs)].reshape(
            values.shape[:-1] + (len(pairs), 4))
        mixed = (corners[..., 0] - corners[..., 1] - corners[..., 2] + corners[..., 3]) / (
            4.0 * STEP ** 2)
        rows, columns = np.array(pairs).T
        hessian[..., rows, columns] = mixed
        hessian[..., columns, rows] = mixed
    return centre, gradient, hessian


def positive_definite(matrices):
    """Whether each of the symmetric `matrices` (..., n, n) is positive definite to working
    precision: its least eigenvalue exceeds n × machine epsilon × its largest (a matrix with
    a zero row, a parameter the objective does not feel, has a least eigenvalue of rounding
    size and either sign, depending on the platform's linear algebra)."""
    eigenvalues = np.linalg.eigvalsh(matrices)
    count = eigenvalues.shape[-1]
    return eigenvalues[..., 0] > count * np.finfo(float).eps * np.abs(eigenvalues[..., -1])


def _batched_solve(matrices, vectors):
    """x with matrices @ x = vectors for a stack of systems (..., n, n) and (..., n).

    numpy's batched solve raises for the whole stack where one matrix is exactly singular (a
    direction in which one train's likelihood is flat to the last bit); there the stack is
    solved by the pseudo-inverse instead, the least-norm step, so the other trains' steps are
    those of the plain solve and the singular one takes no step along its flat direction.
    """
    try:
        return np.linalg.solve(matrices, vectors[..., None])[..., 0]
    except np.linalg.LinAlgError:
        return (np.linalg.pinv(matrices) @ vectors[..., None])[..., 0]


def _newton(objective, start, free, units, trains, lower, upper, iterations, reference=None,
            soft=()):
    """Minimize `objective` over the `free` columns for every (train, start) row at once.

    Damped Newton steps (H + λ·diag|H|) with central differences, all rows' stencils in one
    objective call (a row that has converged is left as it is and no longer evaluated); the
    units of the free coordinates follow the standard errors (√(2/H_ii)) from one iteration
    to the next. Steps are clipped to the bounds and to ±3 units; a step
    that does not lower the objective is retried with 8× the damping.

    Parameters
    ----------
    objective : callable
        ``objective(rows (trains, points, P), trains) -> (trains, points)``.
    start : ndarray, shape (trains, starts, P)
    free : list of int
        Columns fitted.
    units : ndarray, shape (trains, starts, len(free))
        Initial coordinate units (about a standard error).
    trains : ndarray of int
    lower, upper : ndarray, shape (P,)
        Bounds of the steps.
    iterations : int
    reference : ndarray, shape (trains,), optional
        −2 ln L of each train's best fit: a row far above it (a constrained fit that misses,
        such as σ_ε = 0 on a scattered train) needs less precision, CONVERGED plus 1e-3 of
        its excess.
    soft : sequence of int
        Columns whose bounds limit the steps but not the objective (ln σ). The others' units
        are kept small enough for the stencil to stay inside their bounds; the soft ones' at
        most SOFT_UNIT_MAX.

    After ten iterations a row more than FAR above `reference`, or (without a reference)
    above a converged start of its train, is left where it is.

    Returns
    -------
    _Fits
        Best rows, their values and the covariance 2H⁻¹ of the free parameters there.
    """
    params = np.array(start, float)
    shape, count = params.shape[:2], len(free)
    units = np.broadcast_to(np.asarray(units, float), shape + (count,)).copy()
    offsets, pairs = _stencil(count)
    damping = np.ones(shape)
    evaluations = 0
    low, high = lower[free], upper[free]
    hard = np.array([f not in soft for f in free])

    def capped(units, params):
        """Units with which the stencil (±STEP units) stays inside hard bounds."""
        inside = np.minimum(params[..., free] - low, high - params[..., free])
        limit = np.maximum(inside, 1e-12 * np.maximum(np.abs(params[..., free]), 1.0)) / (
            2.0 * STEP)
        return np.where(hard, np.minimum(units, limit), np.minimum(units, SOFT_UNIT_MAX))

    units = capped(units, params)

    def evaluate(params, units, active, previous, offsets=offsets):
        """Objective at the stencil's points around the active rows: (trains, starts,
        points), the inactive rows' from `previous` (inf if None)."""
        where = np.nonzero(active)
        rows = np.repeat(params[where][:, None, :], offsets.shape[0], axis=1)
        rows[..., free] += offsets * units[where][:, None, :]
        out = (np.full(shape + (offsets.shape[0],), np.inf) if previous is None
               else previous.copy())
        if rows.shape[0]:
            out[where] = objective(rows, trains[where[0]])
        return out, rows.shape[0] * offsets.shape[0]

    # Rows done (or without a finite objective) are frozen: no longer evaluated or moved.
    frozen = np.zeros(shape, bool)
    values = None
    with np.errstate(invalid="ignore", over="ignore"):  # inf − inf where a point is invalid
        for iteration in range(iterations):
            values, spent = evaluate(params, units, ~frozen, values)
            evaluations += spent
            centre, gradient, hessian = _derivatives(values, count, pairs)
            usable = np.all(np.isfinite(values), axis=-1)
            position = params[..., free]  # where the derivatives are
            scale = np.abs(np.diagonal(hessian, axis1=-2, axis2=-1)) + 1e-12
            system = hessian + damping[..., None, None] * scale[..., :, None] * np.eye(count)
            system = np.where(usable[..., None, None], system, np.eye(count))
            step = -_batched_solve(system, np.where(usable[..., None], gradient, 0.0))
            step = np.clip(np.nan_to_num(step), -3.0, 3.0)
            moved = params.copy()
            moved[..., free] = np.clip(params[..., free] + step * units, low, high)
            actual = (moved[..., free] - params[..., free]) / units
            gain = -np.sum(gradient * actual, axis=-1) - 0.5 * np.einsum(
                "...i,...ij,...j->...", actual, hessian, actual)
            trial, spent = evaluate(moved, units, ~frozen, None, np.zeros((1, count)))
            trial = trial[..., 0]
            evaluations += spent
            better = (trial < centre) & ~frozen
            params = np.where(better[..., None], moved, params)
            damping = np.where(better, np.maximum(damping / 4.0, 1e-6),
                               np.minimum(damping * 8.0, 1e12))
            # Rescale towards the standard errors: marginal ones (2H⁻¹) where the Hessian is
            # positive definite, so that the ±3-unit steps stride along a correlated valley,
            # else conditional ones (2/H_ii) where the curvature is positive; at most 100× per
            # iteration, so that one bad Hessian does not throw the units away.
            diagonal = np.diagonal(hessian, axis1=-2, axis2=-1)
            factor = np.where(usable[..., None] & (diagonal > 0),
                              np.sqrt(2.0 / np.where(diagonal > 0, diagonal, 1.0)), 1.0)
            safe = np.where(usable[..., None, None], hessian, np.eye(count))
            definite = usable & positive_definite(safe)
            marginal = np.diagonal(np.linalg.inv(np.where(definite[..., None, None], safe,
                                                          np.eye(count))), axis1=-2, axis2=-1)
            factor = np.where(definite[..., None], np.sqrt(2.0 * np.abs(marginal)), factor)
            units = np.where(frozen[..., None], units,
                             capped(units * np.clip(factor, 0.01, 100.0), params))
            # Done where the full Newton step would gain less than the tolerance (½gᵀH⁻¹g, H
            # positive definite; a coordinate held at a bound by its gradient left out), or
            # no step is accepted at all. The damped step's own gain says nothing of the
            # distance to the optimum: after rejected steps it is small however far that is.
            tolerance = CONVERGED if reference is None else CONVERGED + 1e-3 * np.maximum(
                centre - reference[:, None], 0.0)
            held = ((position <= low) & (gradient > 0.0)) | ((position >= high)
                                                             & (gradient < 0.0))
            free_gradient = np.where(usable[..., None] & ~held, gradient, 0.0)
            newton = 0.5 * np.sum(free_gradient * _batched_solve(
                np.where(definite[..., None, None], safe, np.eye(count)), free_gradient),
                axis=-1)
            newton = np.where(definite, newton, np.inf)
            done = (newton < tolerance) | (~better & (damping >= 1e12)) | (
                better & (centre - trial < tolerance) & (newton < 10 * tolerance))
            if reference is not None and iteration >= 10:
                # Far beyond every interval's level: where exactly does not matter.
                done |= centre - reference[:, None] > FAR
            if reference is None and shape[1] > 1 and iteration >= 10:
                # A start still far above one of the same train that has converged is left
                # where it is: the fit keeps the best start, and this one is not near it.
                settled = np.where(frozen | done, centre, np.inf).min(axis=1)
                done |= centre - settled[:, None] > FAR
            frozen |= done | ~usable
            if np.all(frozen):
                break
        values, spent = evaluate(params, units, np.ones(shape, bool), None)
        evaluations += spent
        centre, _, hessian = _derivatives(values, count, pairs)
    # A Hessian that is not finite and positive definite gives no covariance (inf).
    usable = np.all(np.isfinite(values), axis=-1)
    hessian = np.where(usable[..., None, None], hessian, np.eye(count))
    definite = usable & positive_definite(hessian)
    inverse = np.linalg.inv(np.where(definite[..., None, None], hessian, np.eye(count)))
    covariance = 2.0 * inverse * units[..., :, None] * units[..., None, :]
    covariance = np.where(definite[..., None, None], covariance, np.inf)
    natural = np.where(usable[..., None, None], hessian / (units[..., :, None]
                                                           * units[..., None, :]), np.nan)
    return _Fits(params, centre, covariance, units, evaluations, natural)
