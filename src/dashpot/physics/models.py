"""The five linear-dashpot contact models: restitution, contact time, capture.

Models (the paper's table letters in brackets):

======  ==================  =====================  ==========================================
model   gravity in contact  contact ends           rebound speed
======  ==================  =====================  ==========================================
Ia (A)  no                  ξ returns to 0         ξ' there
Ib (B)  yes                 ξ returns to 0         ξ' there
IIa (C) no                  F = 0                  ξ' there
IIb (D) yes                 F = 0                  ξ' there (ball still below z = R)
hybrid  yes                 F = 0, as IIb          speed on regaining z = R: √(vf² − 2|ξ_f|)
======  ==================  =====================  ==========================================

All quantities are dimensionless: time in 1/ω0, speed in v* = g/ω0, length in g/ω0².

The brackets of the end of contact of Ib, IIa and IIb, and the Halley iteration solved in them,
are in :mod:`dashpot.physics.brackets`, shared with the ``ode`` method.

References
----------
.. [1] S. P. Bartz, "Coefficient of restitution of a linear dashpot on a rigid surface",
   sections 3-4 (models Ia, Ib, IIa, IIb, hybrid; capture).
.. [2] T. Schwager and T. Pöschel, "Coefficient of restitution and linear-dashpot model
   revisited", Granular Matter 9, 465-469 (2007) (model IIa).
.. [3] M. Nagurka and S. Huang, "A mass-spring-damper model of a bouncing ball",
   Proc. American Control Conference 2004, 499-504 (model Ia).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import elementwise

from .._validation import check_model, check_nonnegative, check_positive
# GRAVITY_MODELS is defined with the brackets (the ode method needs it too) and kept importable
# from here.
from .brackets import GRAVITY_MODELS, _iia_contact_time, _iib_bracket, _kernels  # noqa: F401
from .contact import Damping

__all__ = ["MODELS", "Collision", "collide", "critical_velocity"]

MODELS = ("Ia", "Ib", "IIa", "IIb", "hybrid")
"""Names of the contact models, in the paper's table order (A, B, C, D, hybrid)."""

# Relative accuracy the exact method achieves against the 40-digit reference across the tested
# range (ε, 1 − ε, contact time), away from the ill-conditioned neighbourhood of the critical speed.
EXACT_RTOL = 1e-13

LOG_FLOAT_MAX = np.log(np.finfo(float).max)


@dataclass(frozen=True)
class Collision:
    """Outcome of one impact under a contact model (dimensionless; arrays broadcast).

    Attributes
    ----------
    model : str
        Contact model name.
    eps : ndarray
        Coefficient of restitution ε = rebound speed / impact speed; 0 where captured.
    one_minus_eps : ndarray
        1 − ε, computed without cancellation (keeps its digits for nearly elastic contacts).
    contact_time : ndarray
        Dimensionless contact duration ω0·τ: time of nonzero compression (Ia, Ib, hybrid) or of
        nonzero force (IIa, IIb); inf where captured.
    captured : ndarray of bool
        True where the ball does not rebound (inelastic capture).
    release_depth : ndarray
        Compression ξ at the end of the contact in units of g/ω0² (<= 0): 0 for Ia and Ib;
        the depth where the force vanishes for IIa, IIb and the hybrid (ξ = −2ζ·release_speed).
        Where the ball is captured without release it settles at rest at the static
        equilibrium: −1 with gravity, 0 without.
    release_speed : ndarray
        ξ' at the end of the contact in units of v* (the speed where the force vanishes for the
        force-ending models and the hybrid, ε·ṽ for Ia and Ib); 0 where captured without release.
    method : str
        "exact" or "ode".
    rtol : float
        Relative accuracy of the method: the tested bound for "exact", the integration tolerance
        for "ode".
    """

    model: str
    eps: np.ndarray
    one_minus_eps: np.ndarray
    contact_time: np.ndarray
    captured: np.ndarray
    release_depth: np.ndarray
    release_speed: np.ndarray
    method: str
    rtol: float


def _find_root(func, lower, upper, args):
    """Vectorized bracketed root at machine precision (Chandrupatla, scipy elementwise)."""
    if lower.size == 0:
        return lower.copy()
    result = elementwise.find_root(func, (lower, upper), args=args)
    return result.x


# --- model Ia and IIa: closed forms, gravity-free -------------------------------------------

def _model_ia(zeta, vtilde):
    d = Damping(zeta)
    safe_omega = np.where(d.under, d.omega, 1.0)
    tau = np.where(d.under, np.pi / safe_omega, np.inf)
    exponent = np.where(d.under, zeta * np.pi / safe_omega, np.inf)
    eps = np.exp(-exponent)
    one_minus = -np.expm1(-exponent)
    captured = ~d.under
    return dict(eps=eps, one_minus_eps=one_minus, contact_time=tau, captured=captured,
                release_depth=np.zeros_like(eps), release_speed=eps * vtilde)


def _model_iia(zeta, vtilde):
    d = Damping(zeta)
    tau = _iia_contact_time(d)
    eps = np.exp(-zeta * tau)
    # ξ'(τ) = −(C − ζS)·ṽ reduces to ε·ṽ: at ωτ = 2φ the oscillation factor is exactly −1.
    release_speed = eps * vtilde
    return dict(eps=eps, one_minus_eps=-np.expm1(-zeta * tau), contact_time=tau,
                captured=np.zeros(eps.shape, bool), release_depth=-2.0 * (zeta * release_speed),
                release_speed=release_speed)


# --- models Ib, IIb and hybrid: with gravity, compiled ---------------------------------------

_FIELDS = ("eps", "one_minus_eps", "contact_time", "captured", "release_depth", "release_speed")


def _model_ib(zeta, vtilde):
    # Bracket, capture, return time and the rebound state from the decay of the invariant, in
    # one compiled pass (exact_kernels.ib_collide; the iteration is described in
    # brackets._ib_solve).
    return dict(zip(_FIELDS, _kernels().ib_collide(zeta, vtilde)))


def _model_iib(zeta, vtilde):
    return dict(zip(_FIELDS, _kernels().iib_collide(zeta, vtilde, False)))


def _model_hybrid(zeta, vtilde):
    # IIb's release, then the climb back to z = R: v1² = vf² − 4ζvf, rebound only if vf > 4ζ.
    return dict(zip(_FIELDS, _kernels().iib_collide(zeta, vtilde, True)))


_EXACT = {"Ia": _model_ia, "Ib": _model_ib, "IIa": _model_iia, "IIb": _model_iib,
          "hybrid": _model_hybrid}


def collide(model, zeta, vtilde, *, method="exact", rtol=None):
    """Restitution, contact time and capture of one impact under a linear-dashpot model.

    Parameters
    ----------
    model : {"Ia", "Ib", "IIa", "IIb", "hybrid"}
        Contact model (see module docstring).
    zeta : array_like
        Damping ratio ζ = β/ω0 (dimensionless), finite and >= 0.
    vtilde : array_like
        Impact speed ṽ = v0/v* with v* = g/ω0 (dimensionless), finite and > 0. Broadcast
        against `zeta`. Ia and IIa do not depend on it except through the release speed.
    method : {"exact", "ode"}, default "exact"
        "exact": closed-form trajectories with vectorized bracketed root finding at machine
        precision (relative error below ``EXACT_RTOL`` = 1e-13 in ε, 1 − ε and contact time
        against a 40-digit reference, except within ~1e-6 of the critical speed where ε ∝
        √(ṽ − ṽc) is ill-conditioned). "ode": direct integration of the equation of motion with
        scipy.integrate.solve_ivp at relative tolerance `rtol`.
    rtol : float, optional
        Integration tolerance for ``method="ode"`` (default 1e-9). Not used by "exact".

    Returns
    -------
    Collision
        ε, 1 − ε, contact time, capture flags, release depth and speed, arrays of the broadcast
        shape.

    Raises
    ------
    ValueError
        Unknown model or method, ζ negative or non-finite, ṽ non-positive or non-finite.

    Notes
    -----
    In contact, ξ'' = −1 − ξ − 2ζξ' (gravity) or ξ'' = −ξ − 2ζξ' (none) with ξ(0) = 0,
    ξ'(0) = −ṽ, and F/(mg) = −ξ − 2ζξ' [1]_. The first end-condition root is bracketed between
    closed-form extrema of ξ (Ib) or F (IIb): capture is decided from the sign there, which is
    exact at the tangency that a grid scan would miss.

    Examples
    --------
    >>> import dashpot
    >>> res = dashpot.collide("Ib", 0.1, [5.0, 23.0])
    >>> bool(res.eps[0] < res.eps[1])  # restitution grows with impact speed under gravity
    True
    """
    model = check_model(model, MODELS)
    zeta = check_nonnegative("zeta", zeta)
    vtilde = check_positive("vtilde", vtilde)
    zeta, vtilde = np.broadcast_arrays(zeta, vtilde)
    shape = zeta.shape
    zeta_flat, vtilde_flat = zeta.ravel().astype(float), vtilde.ravel().astype(float)
    if method == "exact":
        if rtol is not None:
            raise ValueError("rtol is only used by method='ode'; the exact method is always "
                             f"at machine precision (relative error < {EXACT_RTOL:g})")
        fields = _EXACT[model](zeta_flat, vtilde_flat)
        accuracy = EXACT_RTOL
    elif method == "ode":
        from .ode import integrate_collision

        accuracy = 1e-9 if rtol is None else float(rtol)
        if not (1e-13 <= accuracy < 1.0):
            raise ValueError(f"rtol must be in [1e-13, 1), got {rtol!r}")
        fields = integrate_collision(model, zeta_flat, vtilde_flat, accuracy)
    else:
        raise ValueError(f"method must be 'exact' or 'ode', got {method!r}")
    reshaped = {name: np.asarray(value).reshape(shape) for name, value in fields.items()}
    return Collision(model=model, method=method, rtol=accuracy, **reshaped)


# --- critical (capture) speed ---------------------------------------------------------------

def _ib_phase_mismatch(log_v, zeta):
    """Tangency condition of model Ib in y = ln ṽ (ζ < 1); zero at the critical speed.

    At the critical speed ξ returns to 0 with zero velocity at some T. In the rotating frame
    u = η, w = (η' + ζη)/ω of the homogeneous part η = ξ + 1, the flow turns clockwise at rate ω
    and shrinks as e^{−ζt}. From (1, (ζ − ṽ)/ω) at impact to (1, ζ/ω) at T:
    ζT = ½ ln(ω² + (ṽ − ζ)²) and ωT = 2π − atan2(ṽ − ζ, ω) − atan2(ζ, ω). Eliminating T
    leaves this function, strictly increasing in ṽ (derivative ṽ/(ω² + (ṽ − ζ)²)).
    """
    d = Damping(zeta)
    omega = d.omega
    large = log_v > 20.0
    v = np.exp(np.where(large, 0.0, log_v))
    inv_v = np.exp(-np.where(large, log_v, 0.0))
    # ½ ln(ω² + (ṽ − ζ)²) = ½ ln(1 + ṽ(ṽ − 2ζ)); for huge ṽ in terms of 1/ṽ (no overflow).
    shrink_small = 0.5 * np.log1p(v * (v - 2.0 * zeta))
    rest = 1.0 - zeta * inv_v
    shrink_large = log_v + np.log1p(-zeta * inv_v) + 0.5 * np.log1p((omega * inv_v / rest) ** 2)
    shrink = np.where(large, shrink_large, shrink_small)
    turn_small = np.arctan2(v - zeta, omega)
    turn_large = 0.5 * np.pi - np.arctan2(omega * inv_v, rest)
    turn = np.where(large, turn_large, turn_small)
    rotation = 2.0 * np.pi - turn - np.arctan2(zeta, omega)
    return shrink - zeta / omega * rotation


def _critical_ib(zeta):
    out = np.where(zeta < 1.0, 0.0, np.inf)
    active = (zeta > 0.0) & (zeta < 1.0)
    z = zeta[active]
    d = Damping(z)
    ratio = z / d.omega
    lower = np.log(0.5 * np.sqrt(np.pi * ratio))
    upper = np.logaddexp(np.log1p(z), 2.5 * np.pi * ratio) + 1e-3
    log_vc = _find_root(_ib_phase_mismatch, lower, upper, (z,))
    out[active] = np.where(log_vc < LOG_FLOAT_MAX, np.exp(np.minimum(log_vc, LOG_FLOAT_MAX)),
                           np.inf)
    return out


def _iib_margin(log_v, zeta):
    """−f at IIb's force minimum as a function of ln ṽ: > 0 where the ball is released."""
    _, _, force_min = _iib_bracket(zeta, np.exp(log_v))
    return -force_min


def _hybrid_margin(log_v, zeta):
    """Release speed minus the 4ζ needed to climb back to z = R (> 0: hybrid rebounds)."""
    fields = _model_iib(np.ascontiguousarray(zeta, dtype=float),
                        np.ascontiguousarray(np.exp(log_v), dtype=float))
    return np.where(fields["captured"], -4.0 * zeta, fields["release_speed"] - 4.0 * zeta)


def _solve_in_log_speed(margin, zeta, log_start, log_min):
    """Root of a margin increasing in ln ṽ: bracket outward from `log_start`, then refine."""
    if zeta.size == 0:
        return zeta.copy()
    bracket = elementwise.bracket_root(margin, log_start, log_start + 1.0, xmin=log_min,
                                       xmax=np.full_like(zeta, 700.0), args=(zeta,))
    found = bracket.success
    log_vc = np.full(zeta.shape, np.inf)
    if np.any(found):
        log_vc[found] = _find_root(margin, bracket.bracket[0][found], bracket.bracket[1][found],
                                   (zeta[found],))
    return log_vc


def _critical_force_models(model, zeta):
    out = np.zeros(zeta.shape)
    active = zeta > 0.0
    z = zeta[active]
    # Start near the small-ζ asymptote ṽc ~ √ζ and where large ζ needs ṽ ~ ζ.
    log_start = np.log(np.sqrt(z) + z)
    log_min = np.full(z.shape, np.log(np.finfo(float).tiny))
    log_iib = _solve_in_log_speed(_iib_margin, z, log_start, log_min)
    if model == "hybrid":
        # The hybrid needs IIb's release and enough speed to climb: search above IIb's ṽc.
        above = np.nextafter(log_iib, np.inf)
        already = _hybrid_margin(above, z) >= 0.0
        log_h = _solve_in_log_speed(_hybrid_margin, z, above + 1e-12, above)
        log_iib = np.where(already, log_iib, log_h)
    out[active] = np.where(log_iib < LOG_FLOAT_MAX, np.exp(np.minimum(log_iib, LOG_FLOAT_MAX)),
                           np.inf)
    return out


def critical_velocity(model, zeta):
    """Dimensionless critical impact speed ṽc below which the ball is captured.

    Parameters
    ----------
    model : {"Ia", "Ib", "IIa", "IIb", "hybrid"}
    zeta : array_like
        Damping ratio ζ = β/ω0, finite and >= 0.

    Returns
    -------
    ndarray
        ṽc = vc/v* (v* = g/ω0): 0 where the model always rebounds (Ia for ζ < 1, IIa always,
        every model at ζ = 0), inf where it never does (Ia and Ib for ζ >= 1, and Ib just below
        ζ = 1 where ṽc exceeds the float64 range).

    Notes
    -----
    Ib: closed-form tangency condition solved in ln ṽ (see ``_ib_phase_mismatch``); it grows
    like exp(πζ/√(1 − ζ²)) and diverges as ζ → 1⁻, so Ib captures at every speed from ζ = 1 on
    ([1]_, section "Inelastic capture"). IIb: the speed at which the force minimum touches zero.
    Hybrid: the speed at which IIb's release speed vf equals 4ζ, i.e. just enough to climb the
    release depth |ξ_f| = 2ζvf back to the undeformed position.
    """
    model = check_model(model, MODELS)
    zeta = check_nonnegative("zeta", zeta)
    flat = np.asarray(zeta, dtype=float).ravel()
    if model == "Ia":
        out = np.where(flat < 1.0, 0.0, np.inf)
    elif model == "IIa":
        out = np.zeros(flat.shape)
    elif model == "Ib":
        out = _critical_ib(flat)
    else:
        out = _critical_force_models(model, flat)
    return out.reshape(np.shape(zeta))
