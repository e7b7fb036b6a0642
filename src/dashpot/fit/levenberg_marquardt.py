"""The fast level's optimizer: Levenberg–Marquardt with batched finite differences, stopped at
a fraction of a standard error (lmfit's MINPACK leastsq is the other levels' optimizer).

References
----------
Numbered as in :mod:`dashpot.fit`.

.. [7] D. W. Marquardt, "An algorithm for least-squares estimation of nonlinear parameters",
   J. SIAM 11, 431 (1963).
.. [8] H. B. Nielsen, "Damping parameter in Marquardt's method", IMM-REP-1999-05, Technical
   University of Denmark (1999).
"""

from __future__ import annotations

import math

import lmfit
import numpy as np

from .settings import FAST_JACOBIAN_STEP, FAST_STEP_SE, PARAMETERS


def _solve_normal(normal, gradient):
    """x with normal·x = gradient, for one system or a stack of them (last axes).

    By LU where every system is regular, else by the pseudo-inverse: a singular system must
    not stop the rest. A parameter without any effect (a zero row and column, e.g. a train
    captured at every nearby value) gets no step, as the pseudo-inverse would give it, while
    LU still solves for the others.
    """
    inert = np.einsum("...ii->...i", normal) <= 0.0
    if inert.any():
        normal = normal + inert[..., None] * np.eye(normal.shape[-1])
        gradient = np.where(inert, 0.0, gradient)
    try:
        return np.linalg.solve(normal, gradient[..., None])[..., 0]
    except np.linalg.LinAlgError:
        with np.errstate(all="ignore"):
            return np.einsum("...ij,...j->...i", np.linalg.pinv(normal), gradient)


def _levenberg_marquardt(residual_rows, params, linear_columns, *, max_nfev, sigma_known):
    """Levenberg–Marquardt of the fast level: batched differences, stopped at a fraction of
    a standard error.

    Each iteration evaluates the trial point and the forward-difference steps of its Jacobian
    in ONE call of `residual_rows` (one batched train solve), and a parameter that enters
    linearly takes its exact column from `linear_columns`. The iteration stops once the
    Gauss–Newton step still to go, δ = −(JᵀJ)⁻¹Jᵀr, is shorter than FAST_STEP_SE standard
    errors in the fit's own metric: δᵀJᵀJδ <= FAST_STEP_SE² · s², with s² = max(1, χ²/ν)
    (χ²/ν where σ is unknown), the factor by which the covariance is scaled. Damping by the
    diagonal of JᵀJ as in Marquardt [7]_, updated by the gain ratio as in Nielsen [8]_;
    lmfit's leastsq (MINPACK) is the other levels' optimizer.

    Parameters
    ----------
    residual_rows : callable
        ``residual_rows(values)`` with values of shape (sets, parameters) returns the
        normalized residuals, shape (sets, n); the columns are PARAMETERS, then any further
        parameters of `params` in their order.
    params : lmfit.Parameters
        Start values; which are varied. Updated in place to the fitted values and errors (and
        returned as the result's ``params``): copying lmfit parameters costs more than an
        iteration here.
    linear_columns : dict
        Parameter name -> its exact Jacobian column (for parameters entering linearly).
    max_nfev : int
        Largest number of parameter sets evaluated.
    sigma_known : bool
        Whether the residuals are normalized by known uncertainties (else the covariance is
        scaled by χ²/ν, as lmfit's ``scale_covar``).

    Returns
    -------
    lmfit.minimizer.MinimizerResult
        With the fields the fit reads: params (values and stderr), var_names, covar, chisqr,
        redchi, nfree, ndata, nfev, residual, success, message, aic, bic.
    """
    # PARAMETERS, then any further parameters of `params` (the flight's) in their order.
    names = PARAMETERS + tuple(name for name in params if name not in PARAMETERS)
    values = np.array([params[name].value for name in names], float)
    varied = [i for i, name in enumerate(names) if params[name].vary]
    differenced = [i for i in varied if names[i] not in linear_columns]

    def evaluate(point):
        """Residuals and Jacobian at `point` (one batched call)."""
        steps = FAST_JACOBIAN_STEP * np.maximum(np.abs(point[differenced]), 1e-12)
        sets = np.repeat(point[None], 1 + len(differenced), axis=0)
        sets[np.arange(1, sets.shape[0]), differenced] += steps
        rows = residual_rows(sets)
        jacobian = np.empty((rows.shape[1], len(varied)))
        for column, i in enumerate(varied):
            if i in differenced:
                k = differenced.index(i)
                jacobian[:, column] = (rows[1 + k] - rows[0]) / steps[k]
            else:
                jacobian[:, column] = linear_columns[names[i]]
        return rows[0], jacobian, sets.shape[0]

    residual, jacobian, nfev = evaluate(values)
    chisqr = float(residual @ residual)
    dof = max(residual.size - len(varied), 1)
    damping, growth = 1e-6, 2.0  # close to Gauss–Newton: the start is near the minimum
    success, message = False, "largest number of evaluations reached"
    while nfev < max_nfev:
        normal, gradient = jacobian.T @ jacobian, jacobian.T @ residual
        newton = -_solve_normal(normal, gradient)
        spread = chisqr / dof if not sigma_known else max(1.0, chisqr / dof)
        if not np.all(np.isfinite(newton)):
            message = "the Jacobian is not finite"
            break
        if newton @ normal @ newton <= FAST_STEP_SE ** 2 * spread:
            success = True
            message = f"converged: the step left is below {FAST_STEP_SE} standard error"
            break
        scale = np.maximum(np.diag(normal), 1e-300)
        try:
            step = np.linalg.solve(normal + damping * np.diag(scale), -gradient)
        except np.linalg.LinAlgError:
            step = newton
        trial = values.copy()
        trial[varied] += step
        trial_residual, trial_jacobian, cost = evaluate(trial)
        nfev += cost
        trial_chisqr = float(trial_residual @ trial_residual)
        # Gain ratio: actual against predicted decrease of χ² (Nielsen's damping update [8]_).
        predicted = -(2.0 * step @ gradient + step @ normal @ step)
        gain = (chisqr - trial_chisqr) / predicted if predicted > 0 else -1.0
        if trial_chisqr < chisqr:
            settled = chisqr - trial_chisqr <= FAST_STEP_SE ** 2 * spread
            values, residual, jacobian = trial, trial_residual, trial_jacobian
            chisqr = trial_chisqr
            if settled and predicted <= FAST_STEP_SE ** 2 * spread:
                # A flat valley (a parameter the data barely determine): χ² no longer moves
                # by what 0.01 standard error would change it.
                success, message = True, "converged: chi-square no longer changes"
                break
            damping *= max(1.0 / 3.0, 1.0 - (2.0 * gain - 1.0) ** 3)
            growth = 2.0
        else:
            damping *= growth
            growth *= 2.0
            if damping > 1e12:
                # No step lowers χ² any more: at the minimum to rounding.
                success, message = True, "converged: no step lowers chi-square"
                break
    normal = jacobian.T @ jacobian
    covar = None
    if np.linalg.matrix_rank(normal) == len(varied):
        covar = np.linalg.inv(normal) * (1.0 if sigma_known else chisqr / dof)
    result = lmfit.minimizer.MinimizerResult()
    result.params = params
    for column, i in enumerate(varied):
        name = names[i]
        result.params[name].value = float(values[i])
        result.params[name].stderr = (float(math.sqrt(covar[column, column]))
                                      if covar is not None else None)
    ndata, nvarys = residual.size, len(varied)
    result.var_names = [names[i] for i in varied]
    result.covar, result.residual, result.nfev = covar, residual, int(nfev)
    result.chisqr, result.ndata, result.nvarys, result.nfree = chisqr, ndata, nvarys, dof
    result.redchi = chisqr / dof
    result.success, result.message = success, message
    with np.errstate(divide="ignore"):
        neg2_log_likelihood = ndata * np.log(chisqr / ndata)
    result.aic = float(neg2_log_likelihood + 2 * nvarys)
    result.bic = float(neg2_log_likelihood + np.log(ndata) * nvarys)
    return result
