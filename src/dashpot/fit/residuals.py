"""The fit's likelihood: normalized residuals of impact times, measured speeds and Gaussian
priors, many parameter sets at once (χ² is their sum of squares).

References
----------
.. [1] W. H. Press et al., *Numerical Recipes*, 3rd ed., Cambridge (2007), sec. 15.4
   (general linear least squares) and 2.9 (Cholesky decomposition): with correlated errors
   of covariance C = L·Lᵀ, χ² = eᵀC⁻¹e = |L⁻¹e|².
"""

from __future__ import annotations

import numpy as np

from .settings import OMEGA0_RANGE, PARAMETERS, REJECTED


def _residual_rows(values, *, data, predictor, priors):
    """Normalized residuals, one row per parameter set (columns as in PARAMETERS, then any
    flight columns the predictor takes, its ``flight_parameters``).

    Impact-time misfits over their σ, then the measured impact and rebound speeds' misfits
    over theirs (where the table states errors the speeds share, ``data.speed_whitening``
    W times the misfits, so that their sum of squares is eᵀC⁻¹e [1]_), then one row per
    Gaussian prior (name, centre, sd). A set outside the
    physical range (ζ < 0, ω0 above OMEGA0_RANGE, v0 <= 0, a flight the predictor does not
    accept) gets REJECTED everywhere.
    """
    g = data.g
    zeta, v_star, v0, t0 = values.T[:len(PARAMETERS)]
    flight = values[:, len(PARAMETERS):].T
    impact_rows = np.isfinite(data.impact_speed)
    rebound_rows = np.isfinite(data.rebound_speed)
    valid = (zeta >= 0.0) & (v_star > g / OMEGA0_RANGE[1]) & (v0 > 0.0)
    if flight.size:
        valid &= predictor.accepts(*flight)
    out = np.full((values.shape[0], _residual_size(data, priors)), REJECTED)
    if not valid.any():
        return out
    _, times, speeds, rebound = predictor(zeta[valid], g / v_star[valid], v0[valid],
                                          *flight[:, valid])
    parts = [(data.times - t0[valid, None] - times[:, data.index]) / data.sigma]
    whitening = data.speed_whitening
    if whitening is not None:
        # Speeds whose errors are correlated (shared within the run): generalized least
        # squares, the misfits whitened by the Cholesky factor of their covariance [1]_.
        misfit = np.concatenate([
            data.impact_speed[impact_rows] - speeds[:, data.index[impact_rows]],
            data.rebound_speed[rebound_rows] - rebound[:, data.index[rebound_rows]]], axis=1)
        parts.append(misfit @ whitening.T)
    elif impact_rows.any():
        parts.append((data.impact_speed[impact_rows] - speeds[:, data.index[impact_rows]])
                     / data.speed_sigma[impact_rows])
    if rebound_rows.any() and whitening is None:
        parts.append((data.rebound_speed[rebound_rows] - rebound[:, data.index[rebound_rows]])
                     / data.speed_sigma[rebound_rows])
    for name, centre, sd in priors:
        parts.append((values[valid, _column(name, predictor), None] - centre) / sd)
    out[valid] = np.concatenate(parts, axis=1)
    return out


def _column(name, predictor):
    """Column of a parameter: PARAMETERS, then the predictor's flight parameters."""
    if name in PARAMETERS:
        return PARAMETERS.index(name)
    return len(PARAMETERS) + predictor.flight_parameters.index(name)


def _residual_size(data, priors):
    """Number of residuals of :func:`_residual_rows`."""
    return (data.times.size + int(np.isfinite(data.impact_speed).sum())
            + int(np.isfinite(data.rebound_speed).sum()) + len(priors))
