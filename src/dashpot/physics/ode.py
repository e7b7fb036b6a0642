"""Collision outcomes by direct integration of the equation of motion (the ``ode`` method).

An independent route to what :mod:`dashpot.physics.models` computes from closed forms, at a
caller-chosen tolerance, and the path for contact laws that have no closed form. All points of a
call are integrated together as one stacked system by scipy.integrate.solve_ivp (DOP853), each
in its own rescaled time σ = t/H so that one step sequence serves them all. The end-of-contact
event is located in two stages: the first integration step over which the end condition changes
sign, then Chandrupatla's bracketing root finder on the event function at σ, evaluated by
integrating from the start of that step to σ (vectorized over points).

The integration window H of each point comes from the linear analysis (half a damped period
past the compression or force minimum, see ``brackets``); where the linear analysis says the contact
never ends (capture), the window is a few natural periods, after which the ODE route reports
capture if it has seen no event. Near the critical speed the event is a near tangency and the
route is only as good as the step sequence that brackets it.

References
----------
.. [1] E. Hairer, S. P. Nørsett and G. Wanner, "Solving Ordinary Differential Equations I",
   2nd ed., Springer (1993), section II.6 (dense output, event location), II.10 (DOP853).
.. [2] T. R. Chandrupatla, "A new hybrid quadratic/bisection algorithm for finding the zero of a
   nonlinear function without using derivatives", Adv. Eng. Software 28, 145-149 (1997).
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import elementwise

from .brackets import GRAVITY_MODELS, _iia_contact_time, _iib_bracket, _ib_bracket
from .contact import Damping

__all__ = ["integrate_collision"]

CHUNK = 2048  # points integrated together: bounds the memory of the stored step states
SAMPLES = 64  # smallest number of integration steps across each point's window


def _rhs(gravity, zeta, window):
    """Right-hand side in rescaled time σ for stacked states [ξ_0, ξ'_0, ξ_1, ξ'_1, ...]."""

    def rhs(_sigma, state):
        xi, rate = state[0::2], state[1::2]
        out = np.empty_like(state)
        out[0::2] = window * rate
        out[1::2] = window * (-gravity - xi - 2.0 * zeta * rate)
        return out

    return rhs


def _end_condition(model, zeta, xi, rate):
    """Event function, negative during contact: ξ (Ia, Ib) or −F/(mg) = ξ + 2ζξ' (others)."""
    if model in ("Ia", "Ib"):
        return xi
    return xi + 2.0 * zeta * rate


def _integrate(gravity, zeta, window, start_state, span, rtol, atol, max_step=np.inf):
    """Integrate stacked points from σ = 0 to σ = `span` (per point, via rescaling)."""
    scaled_window = window * span
    solution = solve_ivp(_rhs(gravity, zeta, scaled_window), (0.0, 1.0), start_state.ravel(),
                         method="DOP853", rtol=rtol, atol=np.repeat(atol, 2),
                         max_step=max_step)
    return solution


def _window(model, zeta, vtilde):
    """Integration window H (dimensionless time) that bounds the end of the contact."""
    d = Damping(zeta)
    fallback = 4.0 * np.pi / np.maximum(zeta, 1.0)
    if model == "Ia":
        bound = 2.0 * d.half_period
    elif model == "IIa":
        bound = 1.5 * _iia_contact_time(d)
    elif model == "Ib":
        bound = 1.05 * _ib_bracket(zeta, vtilde)[1]
    else:
        bound = 1.05 * _iib_bracket(zeta, vtilde)[1]
    return np.where(np.isfinite(bound), bound, fallback)


def _chunk(model, zeta, vtilde, rtol):
    gravity = 1.0 if model in GRAVITY_MODELS else 0.0
    n = zeta.size
    window = _window(model, zeta, vtilde)
    scale = np.maximum(vtilde, 1.0)
    atol = 1e-3 * rtol * scale
    start = np.column_stack([np.zeros(n), -vtilde])
    # At least SAMPLES step ends per window, so that no end of contact hides inside a step.
    run = _integrate(gravity, zeta, window, start, np.ones(n), rtol, atol,
                     max_step=1.0 / SAMPLES)
    states = run.y.reshape(n, 2, -1)
    condition = _end_condition(model, zeta[:, None], states[:, 0, :], states[:, 1, :])
    # First step end (after σ = 0, where ξ = 0 by construction) at which the contact has ended.
    ended = condition[:, 1:] >= 0.0
    found = ended.any(axis=1)
    step = np.argmax(ended, axis=1)  # index into run.t[1:]
    sigma_lo = run.t[step]
    sigma_hi = run.t[step + 1]
    state_lo = states[np.arange(n), :, step]

    def event(sigma, zeta_, window_, sigma_lo_, xi_lo, rate_lo, atol_):
        if sigma.size == 0:
            return sigma.copy()
        span = sigma - sigma_lo_
        part = _integrate(gravity, zeta_, window_, np.column_stack([xi_lo, rate_lo]), span,
                          rtol, atol_)
        end = part.y[:, -1].reshape(-1, 2)
        return _end_condition(model, zeta_, end[:, 0], end[:, 1])

    sigma_event = np.full(n, np.nan)
    idx = np.flatnonzero(found)
    if idx.size:
        root = elementwise.find_root(
            event, (sigma_lo[idx], sigma_hi[idx]),
            args=(zeta[idx], window[idx], sigma_lo[idx], state_lo[idx, 0], state_lo[idx, 1],
                  atol[idx]),
            tolerances=dict(xrtol=rtol * 1e-2))
        # Where re-integration from the step start disagrees with the first pass about the
        # sign at the step end (a near tangency), interpolate linearly inside the step.
        c_lo = condition[idx, step[idx]]
        c_hi = condition[idx, step[idx] + 1]
        fraction = np.clip(-c_lo / np.where(c_hi > c_lo, c_hi - c_lo, 1.0), 0.0, 1.0)
        linear = sigma_lo[idx] + fraction * (sigma_hi[idx] - sigma_lo[idx])
        sigma_event[idx] = np.where(root.success & np.isfinite(root.x), root.x, linear)
    # State at the event, integrated once more from the start of its step.
    xi_end = np.zeros(n)
    rate_end = np.zeros(n)
    if idx.size:
        final = _integrate(gravity, zeta[idx], window[idx],
                           state_lo[idx], sigma_event[idx] - sigma_lo[idx], rtol, atol[idx])
        end = final.y[:, -1].reshape(-1, 2)
        xi_end[idx], rate_end[idx] = end[:, 0], end[:, 1]
    return found, window * sigma_event, xi_end, rate_end


def integrate_collision(model, zeta, vtilde, rtol):
    """ε, 1 − ε, contact time, capture and release of each point by direct integration.

    Parameters
    ----------
    model : str
        One of the five contact models.
    zeta, vtilde : ndarray
        Flat arrays of damping ratio ζ and dimensionless impact speed ṽ (validated).
    rtol : float
        Relative tolerance of the integration (and of the event location).

    Returns
    -------
    dict of ndarray
        The fields of :class:`dashpot.physics.models.Collision`.
    """
    n = zeta.size
    found = np.zeros(n, bool)
    tau = np.full(n, np.inf)
    xi_end = np.zeros(n)
    rate_end = np.zeros(n)
    order = np.argsort(zeta, kind="stable")  # similar stiffness integrates together
    for start in range(0, n, CHUNK):
        part = order[start:start + CHUNK]
        f, t, x, r = _chunk(model, zeta[part], vtilde[part], rtol)
        found[part], tau[part], xi_end[part], rate_end[part] = f, t, x, r
    gravity = model in GRAVITY_MODELS
    rebound = found & (rate_end > 0.0)
    release_speed = np.where(rebound, rate_end, 0.0)
    if model == "hybrid":
        climb_energy = release_speed**2 + 2.0 * xi_end
        rebound &= climb_energy > 0.0
        rebound_speed = np.sqrt(np.where(rebound, climb_energy, 0.0))
        contact = tau + (release_speed - rebound_speed)
    else:
        rebound_speed = release_speed
        contact = tau
    eps = np.where(rebound, rebound_speed / vtilde, 0.0)
    released = found & (release_speed > 0.0)
    at_rest = -1.0 if gravity else 0.0
    return dict(eps=eps, one_minus_eps=1.0 - eps,
                contact_time=np.where(rebound, contact, np.inf), captured=~rebound,
                release_depth=np.where(released, xi_end, at_rest),
                release_speed=np.where(released, release_speed, 0.0))
