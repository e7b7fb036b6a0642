"""A ladder of restitution laws ε(v), beside the five dashpot models, as rebound maps.

Each law gives the coefficient of restitution ε at the impact speed v and its speed slope, and
a ``rebound`` adapter turns it into the rebound speed R(v) = ε(v)·v with dR/dv, the form
:class:`dashpot.likelihood.TrainModel` takes. The registry :data:`LAWS` lists every law with its
parameters' names, units, fit bounds and start values, so that a new law is one function plus
one registry entry.

==================  ===========================================  ======================  =====
law                 ε(v)                                         parameters              ref.
==================  ===========================================  ======================  =====
constant            e                                            e                       —
linear              e0 − α·v                                     e0, α (s/m)             —
power               a·v^(−b)  (v in m/s)                         a, b                    —
quadratic           e0 − c·v²                                    e0, c (s²/m²)           —
viscoelastic-hertz  1 − C1·δ + C2·δ² + δ·q(δ),  δ = κ·v^(1/5)   κ (s^(1/5)/m^(1/5))     [1]_
hunt-crossley       root of ln((1 + d)/(1 − dε)) = d(1 + ε),     χ = λ/k (s/m)           [2]_
                    d = χ·v
Ia … hybrid         dashpot model at ṽ = v/v*                     ζ, v* = g/ω0 (m/s)      [3]_
==================  ===========================================  ======================  =====

Domain. A law never returns ε outside [0, 1] silently: where its formula leaves [0, 1] (a
constant above 1, a linear law past v = e0/α, a power law below the speed where a·v^(−b) = 1)
ε is clipped to the bound, its slope set to 0 and the point flagged in
:attr:`Restitution.outside`; the same flag marks the viscoelastic law beyond its table
(below). A fit should keep the flagged points out (or note them):
clipping is what keeps the train simulations NaN-free, not a physical statement.

Viscoelastic Hertz. The contact m·ξ'' = −k·ξ^(3/2) − (3/2)·A·k·ξ^(1/2)·ξ' [4]_, ending where
ξ returns to 0, scales with ξ = L·x, t = (L/v)·s, L = (m v²/k)^(2/5) into
x'' = −x^(3/2) − δ·x^(1/2)·x' with the single number δ = (3/2)·A·(k/m)^(2/5)·v^(1/5) = κ·v^(1/5).
Ramírez et al. [1]_ give 1 − ε = C1·δ − C2·δ² + …, C1 = 1.15344, C2 = 0.79826 (= 3C1²/5).
Truncated at second order the series is off by about 0.5·δ³ (4e-6 at δ = 0.02, 5e-4 at 0.1,
3.7e-3 at 0.2) and turns back up beyond δ = C1/2C2 ≈ 0.72, so the law is
ε = 1 − C1·δ + C2·δ² + δ·q(δ), with the remainder q (which also absorbs the rounding of the
published C1, about 1e-5) a Chebyshev interpolant of degree 20 on [0, 2] of the contact
integrated directly (:func:`viscoelastic_contact_restitution`, solve_ivp to 1e-13) at its
Chebyshev points, built once per process when the law is first used (0.15 s). Against direct
integration it is accurate to about 1e-11 on 0 <= δ <= VISCOELASTIC_DELTA_MAX = 2 (ε from 1
down to 0.095), and exact at δ = 0; beyond, ε is held at ε(2) and the points are flagged as
outside.

Hunt–Crossley. The contact m·ξ'' = −k·ξ^n − λ·ξ^n·ξ' [2]_ has a first integral: with y = ξ',
y·dy/dξ = −(k/m)ξ^n(1 + χy), so y/χ − ln(1 + χy)/χ² + (k/m)ξ^(n+1)/(n + 1) is conserved.
Between ξ = 0 at impact (y = v) and at separation (y = −εv) it gives the implicit relation in
the table, exact for every exponent n. It is solved as ε² = ψ(d)/ψ(−dε) with
ψ(x) = (ln(1 + x) − x)/x² (a series near 0, so nothing cancels for nearly elastic contacts)
for d <= 1, and in u = −ln(1 − dε) above, where 1 − dε is exponentially small, both by
safeguarded Newton steps (:func:`hunt_crossley_restitution`); for small d, 1 − ε ≈ 2d/3.

Dashpot models: ε from :func:`dashpot.physics.models.collide` (exact method) at ṽ = v/v*. The
slope dε/dṽ is analytic: the rebound state w at the end condition τ(ṽ) is differentiated
implicitly, with the trajectory's sensitivity to ṽ equal to −S(t) (the fundamental solution of
:mod:`dashpot.physics.contact`): Ib: dτ/dṽ = S/w, dw/dṽ = −(1 + 2ζw)·S/w − S'; IIb (released
at F = 0 with ξ'' = −1): dτ/dṽ = (S + 2ζS')/(w − 2ζ), dw/dṽ = −dτ/dṽ − S'; hybrid:
v1 = √(w² − 4ζw), dv1/dṽ = (w − 2ζ)/v1·dw/dṽ, climbing for w − v1 more; Ia, IIa: ε does not
depend on ṽ. All evaluated at τ, S' = C − ζS. :func:`dashpot_contact_time` gives the contact
duration in s with its slope, for ``TrainModel.contact_time``.

References
----------
.. [1] R. Ramírez, T. Pöschel, N. V. Brilliantov and T. Schwager, "Coefficient of restitution
   of colliding viscoelastic spheres", Phys. Rev. E 60, 4465-4472 (1999).
.. [2] K. H. Hunt and F. R. E. Crossley, "Coefficient of restitution interpreted as damping in
   vibroimpact", J. Appl. Mech. 42, 440-445 (1975).
.. [3] S. P. Bartz, "Coefficient of restitution of a linear dashpot on a rigid surface",
   sections 3-4 (models Ia, Ib, IIa, IIb, hybrid).
.. [4] N. V. Brilliantov, F. Spahn, J.-M. Hertzsch and T. Pöschel, "Model for collisions in
   granular gases", Phys. Rev. E 53, 5382-5392 (1996).
.. [5] L. N. Trefethen, *Approximation Theory and Approximation Practice*, SIAM (2013),
   ch. 2-8 (interpolation in Chebyshev points and its convergence for analytic functions).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

from .._validation import check_nonnegative
from .contact import Damping, basis
from .models import MODELS, collide

__all__ = ["LADDER", "LAWS", "LawParameter", "Restitution", "RestitutionLaw",
           "dashpot_contact_time", "dashpot_step", "hunt_crossley_restitution",
           "restitution"]

VISCOELASTIC_C1 = 1.15344
"""First coefficient of the viscoelastic series, Ramírez et al. (1999), eq. for γ1."""
VISCOELASTIC_C2 = 0.79826
"""Second coefficient of the viscoelastic series, Ramírez et al. (1999) (= 3C1²/5)."""
VISCOELASTIC_DELTA_MAX = 2.0
"""Largest δ = κv^(1/5) of the tabulated viscoelastic law (ε ≈ 0.095 there): beyond, ε is
held at its value there and the points are flagged as outside."""
_VISCOELASTIC_DEGREE = 20  # of the Chebyshev interpolant of the series' remainder


@dataclass(frozen=True)
class LawParameter:
    """One parameter of a restitution law, with what a fit needs to know of it.

    Attributes
    ----------
    name : str
        Name as fitted (an lmfit Parameter name).
    unit : str
        SI unit ("" if dimensionless).
    lower, upper : float
        Default fit bounds.
    start : float
        Default start value, inside the bounds.
    description : str
        What it is, in a few words.
    """

    name: str
    unit: str
    lower: float
    upper: float
    start: float
    description: str


@dataclass(frozen=True)
class Restitution:
    """ε of a law at each impact speed (arrays of the broadcast shape).

    Attributes
    ----------
    eps : ndarray
        Coefficient of restitution, in [0, 1].
    speed_slope : ndarray
        v·dε/dv (dimensionless; finite at v = 0, unlike dε/dv for the viscoelastic law); 0 where
        ε is clipped.
    outside : ndarray of bool
        Where the law's formula left [0, 1] and ε was clipped, or (viscoelastic Hertz) where δ
        is beyond its table (VISCOELASTIC_DELTA_MAX).
    """

    eps: np.ndarray
    speed_slope: np.ndarray
    outside: np.ndarray

    def slope(self, speed):
        """dε/dv in s/m at `speed` (m/s); ±inf where v = 0 with a nonzero speed slope."""
        speed = np.asarray(speed, dtype=float)
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(self.speed_slope == 0.0, 0.0, self.speed_slope / speed)


@dataclass(frozen=True)
class RestitutionLaw:
    """A restitution law of the ladder: ε(v; params) with its metadata.

    Attributes
    ----------
    name : str
        Registry key.
    formula : str
        ε(v) in one line, for reports.
    parameters : tuple of LawParameter
        In the order the law function takes them.
    function : callable
        ``function(speed, *params) -> (eps, speed_slope, outside)`` on broadcast arrays, ε not
        yet clipped to [0, 1] (``outside`` marks the law's own domain limits).
    reference : str
        Where the law comes from.
    """

    name: str
    formula: str
    parameters: tuple[LawParameter, ...]
    function: Callable
    reference: str

    @property
    def parameter_names(self):
        """Names of the parameters, in call order."""
        return tuple(p.name for p in self.parameters)

    def __call__(self, speed, *params):
        """ε at impact speed(s) `speed` in m/s (>= 0) under parameters `params`.

        Returns
        -------
        Restitution
            ε clipped to [0, 1], v·dε/dv, and where clipping (or the law's domain) applied.

        Raises
        ------
        ValueError
            Wrong number of parameters, a speed negative or non-finite, a parameter non-finite
            or outside the law's physical domain (named in the message).
        """
        if len(params) != len(self.parameters):
            raise ValueError(f"restitution law {self.name!r} takes {len(self.parameters)} "
                             f"parameters ({', '.join(self.parameter_names)}); "
                             f"got {len(params)}")
        speed = check_nonnegative("speed", speed)
        params = [_finite(p.name, value) for p, value in zip(self.parameters, params)]
        arrays = np.broadcast_arrays(speed, *params)
        eps, speed_slope, outside = self.function(*arrays)
        below, above = eps < 0.0, eps > 1.0
        clipped = below | above
        return Restitution(eps=np.clip(eps, 0.0, 1.0),
                           speed_slope=np.where(clipped, 0.0, speed_slope),
                           outside=clipped | outside)

    def rebound(self, speed, *params):
        """Rebound speed R(v) = ε(v)·v in m/s and dR/dv, for :class:`TrainModel`.

        Parameters
        ----------
        speed : array_like
            Impact speed v in m/s, >= 0.
        *params : array_like
            The law's parameters (see :attr:`parameters`), broadcast against `speed`.

        Returns
        -------
        rebound, slope : ndarray
            ε·v in m/s and dR/dv = ε + v·dε/dv (dimensionless).
        """
        law = self(speed, *params)
        return law.eps * np.asarray(speed, dtype=float), law.eps + law.speed_slope

    def bind(self, *params):
        """The rebound map at fixed parameters: ``u -> (R(u), dR/du)`` (``TrainModel.rebound``)."""
        return lambda speed: self.rebound(speed, *params)


def _finite(name, value):
    array = np.asarray(value, dtype=float)
    if not np.all(np.isfinite(array)):
        raise ValueError(f"{name} must be finite; got {value!r}")
    return array


# --- one-line laws ----------------------------------------------------------------------------

def _no_flag(shape):
    return np.zeros(shape, bool)


def constant(speed, e):
    """ε = e at every speed."""
    return e.copy(), np.zeros(speed.shape), _no_flag(speed.shape)


def linear(speed, e0, alpha):
    """ε = e0 − α·v (α in s/m)."""
    return e0 - alpha * speed, -alpha * speed, _no_flag(speed.shape)


def quadratic(speed, e0, c):
    """ε = e0 − c·v² (c in s²/m²)."""
    term = c * speed * speed
    return e0 - term, -2.0 * term, _no_flag(speed.shape)


def power(speed, a, b):
    """ε = a·v^(−b) with v in m/s (a is ε at 1 m/s), v·dε/dv = −b·ε.

    Evaluated in logarithms and capped at e > 1 before the exponential, so v → 0 gives no
    overflow: there ε is clipped to 1 (b > 0) or tends to 0 (b < 0).
    """
    tiny = np.finfo(float).tiny
    with np.errstate(divide="ignore"):
        log_eps = np.log(np.maximum(a, 0.0)) - b * np.log(np.maximum(speed, tiny))
    eps = np.exp(np.minimum(log_eps, 1.0))
    # A negative a gives no real power law: ε < 0 is clipped (and flagged) by the caller.
    eps = np.where(a < 0.0, -1.0, eps)
    return eps, -b * eps, _no_flag(speed.shape)


def viscoelastic_hertz(speed, kappa):
    """1 − ε = C1·δ − C2·δ² − δ·q(δ), δ = κ·v^(1/5), with the remainder q tabulated from the
    integrated contact (module notes)."""
    if np.any(kappa < 0.0):
        raise ValueError(f"kappa must be >= 0 (no energy gain in contact); got {kappa!r}")
    delta = kappa * speed ** 0.2
    outside = delta > VISCOELASTIC_DELTA_MAX
    held = np.minimum(delta, VISCOELASTIC_DELTA_MAX)
    table, table_slope = _viscoelastic_remainder_table()
    remainder, remainder_slope = table(held), table_slope(held)
    eps = 1.0 - VISCOELASTIC_C1 * held + VISCOELASTIC_C2 * held * held + held * remainder
    eps_slope = (-VISCOELASTIC_C1 + 2.0 * VISCOELASTIC_C2 * held + remainder
                 + held * remainder_slope)
    # v·dε/dv = (δ/5)·dε/dδ; held beyond the table, ε does not change.
    return eps, np.where(outside, 0.0, 0.2 * held * eps_slope), outside


def viscoelastic_contact_restitution(delta):
    """ε of the scaled viscoelastic Hertz contact x'' = −x^(3/2) − δ·x^(1/2)·x' by direct
    integration (solve_ivp, DOP853), from x = 0, x' = 1 until x returns to 0.

    Parameters
    ----------
    delta : float
        δ = κ·v^(1/5) >= 0 (dimensionless).

    Returns
    -------
    float
        ε = −x' at the end of the contact; absolute error about 1e-9 (the force is not
        smooth at x = 0, where the integration starts and ends).

    Notes
    -----
    The first microsecond of scaled time is taken from the start's expansion
    x = t − (4/15)·δ·t^(5/2), x' = 1 − (2/3)·δ·t^(3/2) (the Hertz term enters at t^(5/2) in x'),
    so that the integrator does not step across the square root at x = 0.
    """
    start = 1e-6

    def motion(_, state):
        x = max(state[0], 0.0)
        root = math.sqrt(x)
        return [state[1], -x * root - delta * root * state[1]]

    def separation(_, state):
        return state[0]

    separation.terminal, separation.direction = True, -1
    initial = [start - 4.0 / 15.0 * delta * start ** 2.5, 1.0 - 2.0 / 3.0 * delta * start ** 1.5]
    solution = solve_ivp(motion, (start, 1e4), initial, method="DOP853", events=separation,
                         rtol=1e-13, atol=1e-15, first_step=1e-6)
    return float(-solution.y_events[0][0][1])


@functools.lru_cache(maxsize=1)
def _viscoelastic_remainder_table():
    """Chebyshev interpolant [5]_ of q(δ) = (ε − 1 + C1·δ − C2·δ²)/δ on
    [0, VISCOELASTIC_DELTA_MAX] from the integrated contact at its Chebyshev points (which
    leave out δ = 0), and its derivative; built once per process (0.15 s)."""
    def remainder(delta):
        eps = np.array([viscoelastic_contact_restitution(float(d)) for d in np.ravel(delta)])
        return (eps - 1.0 + VISCOELASTIC_C1 * delta - VISCOELASTIC_C2 * delta * delta) / delta

    table = np.polynomial.Chebyshev.interpolate(remainder, _VISCOELASTIC_DEGREE,
                                                domain=[0.0, VISCOELASTIC_DELTA_MAX])
    return table, table.deriv()


# --- Hunt–Crossley ----------------------------------------------------------------------------

def hunt_crossley_restitution(damping):
    """ε of the Hunt–Crossley contact and dε/dd, at the dimensionless damping d = χ·v.

    Parameters
    ----------
    damping : array_like
        d = (λ/k)·v >= 0, finite.

    Returns
    -------
    eps, slope : ndarray
        ε(d) in (0, 1] solving ln((1 + d)/(1 − dε)) = d(1 + ε), and dε/dd.

    Notes
    -----
    For d <= 1 the root is found as ε² = ψ(d)/ψ(−dε) on ε ∈ [0, 1] (no cancellation as d → 0),
    starting from 1 − 2d/3. For d > 1, 1 − dε is exponentially small (e^(−d) roughly) and would
    be lost to rounding: there the unknown is u = −ln(1 − dε), which solves the convex
    u + e^(−u) − 1 = d − ln(1 + d) on [0, d − ln(1 + d) + 1], and ε = (1 − e^(−u))/d. Both by
    safeguarded Newton steps (5-8 evaluations), point by point in a compiled loop.
    """
    # Imported here: numba compiles (or loads) the kernels only when the law is first used.
    from .law_kernels import hunt_crossley_many

    d = check_nonnegative("damping", damping).astype(float)
    flat = np.ascontiguousarray(d).ravel()
    eps, slope = np.empty(flat.size), np.empty(flat.size)
    hunt_crossley_many(flat, eps, slope)
    return eps.reshape(d.shape), slope.reshape(d.shape)


def hunt_crossley(speed, chi):
    """ε of the Hunt–Crossley law at d = χ·v (χ = λ/k in s/m)."""
    if np.any(chi < 0.0):
        raise ValueError(f"chi must be >= 0 (no energy gain in contact); got {chi!r}")
    damping = chi * speed
    eps, slope = hunt_crossley_restitution(damping)
    return eps, damping * slope, _no_flag(speed.shape)


# --- dashpot models ---------------------------------------------------------------------------

def _dashpot_state(model, zeta, vtilde, level="exact"):
    """ε, dw/dṽ (w = εṽ), contact time ω0τ and dτ/dṽ of a dashpot model (dimensionless), from
    the exact collision or (level "fast", "standard") its certified surrogate tables."""
    vtilde = np.maximum(vtilde, np.finfo(float).tiny)  # ṽ = 0: the limit, captured or not
    if level == "exact":
        hit = collide(model, zeta, vtilde)
    else:
        # Imported here: the surrogate loads numba tables that only these levels need.
        from .surrogate import surrogate_collide

        hit = surrogate_collide(model, zeta, vtilde, level=level)
    eps, tau = hit.eps, hit.contact_time
    w_slope = eps.copy()
    tau_slope = np.zeros(eps.shape)
    rebound = ~hit.captured
    if model in ("Ib", "IIb", "hybrid") and np.any(rebound):
        z, v = zeta[rebound], vtilde[rebound]
        vf = hit.release_speed[rebound]
        t = tau[rebound]
        if model == "hybrid":
            v1 = eps[rebound] * v
            t = t - (vf - v1)  # the climb from the release depth takes vf − v1 (g = 1)
        c, s = basis(Damping(z), t)
        s_slope = c - z * s
        if model == "Ib":
            dt = s / vf
            dw = -(1.0 + 2.0 * z * vf) * dt - s_slope
        else:
            dt = (s + 2.0 * z * s_slope) / (vf - 2.0 * z)
            dw = -dt - s_slope
        if model == "hybrid":
            dv1 = (vf - 2.0 * z) / v1 * dw
            dt, dw = dt + dw - dv1, dv1
        w_slope[rebound], tau_slope[rebound] = dw, dt
    w_slope = np.where(rebound, w_slope, 0.0)
    tau_slope = np.where(rebound, tau_slope, 0.0)
    return eps, w_slope, tau, tau_slope


def _dashpot_law(model):
    def function(speed, zeta, v_star):
        if np.any(zeta < 0.0) or np.any(v_star <= 0.0):
            raise ValueError(f"model {model}: zeta must be >= 0 and v_star > 0; got "
                             f"zeta={zeta!r}, v_star={v_star!r}")
        shape = speed.shape
        eps, w_slope, _, _ = _dashpot_state(model, zeta.ravel(), (speed / v_star).ravel())
        # ṽ·dε/dṽ = dw/dṽ − ε.
        return eps.reshape(shape), (w_slope - eps).reshape(shape), _no_flag(shape)

    function.__name__ = f"dashpot_{model}"
    function.__doc__ = f"ε of dashpot model {model} at ṽ = v/v* (exact, analytic slope)."
    return function


def dashpot_contact_time(model, speed, zeta, v_star, g):
    """Contact duration of a dashpot model in s and its slope, for ``TrainModel.contact_time``.

    Parameters
    ----------
    model : {"Ia", "Ib", "IIa", "IIb", "hybrid"}
    speed : array_like
        Impact speed v in m/s, >= 0.
    zeta : array_like
        Damping ratio ζ = β/ω0.
    v_star : array_like
        v* = g/ω0 in m/s, > 0.
    g : float or array_like
        Acceleration g (g_eff) in m/s², > 0.

    Returns
    -------
    duration, slope : ndarray
        τ in s (inf where captured) and dτ/dv in s²/m (0 where captured).
    """
    speed = check_nonnegative("speed", speed)
    speed, zeta, v_star, g = np.broadcast_arrays(speed, _finite("zeta", zeta),
                                                 _finite("v_star", v_star), _finite("g", g))
    if np.any(v_star <= 0.0) or np.any(g <= 0.0):
        raise ValueError(f"v_star and g must be > 0; got v_star={v_star!r}, g={g!r}")
    shape = speed.shape
    _, _, tau, tau_slope = _dashpot_state(model, zeta.ravel(), (speed / v_star).ravel())
    omega0 = g.ravel() / v_star.ravel()
    # τ = (ω0τ)/ω0 and dτ/dv = (dω0τ/dṽ)·(1/ω0)·(1/v*) = (dω0τ/dṽ)/g.
    return (tau / omega0).reshape(shape), (tau_slope / g.ravel()).reshape(shape)


def dashpot_step(model, speed, zeta, v_star, g, level="exact"):
    """Rebound speed and contact duration of a dashpot model with their slopes, from one
    evaluation of the collision (``rebound`` and :func:`dashpot_contact_time` each make one).

    Parameters
    ----------
    model, speed, zeta, v_star, g
        As in :func:`dashpot_contact_time`.
    level : {"exact", "fast", "standard"}, default "exact"
        The exact collision, or the surrogate tables of that level
        (:func:`dashpot.physics.surrogate.surrogate_collide`: certified relative errors of
        ε, 1 − ε and the contact time about 1e-6 and 1e-9; the slopes follow from their
        contact time and release speed by the same formulas).

    Returns
    -------
    rebound, rebound_slope : ndarray
        R(v) = ε·v in m/s and dR/dv = dw/dṽ (dimensionless): as ``LAWS[model].rebound``.
    duration, duration_slope : ndarray
        τ in s (inf where captured) and dτ/dv in s²/m: as :func:`dashpot_contact_time`.
    """
    speed = check_nonnegative("speed", speed)
    speed, zeta, v_star, g = np.broadcast_arrays(speed, _finite("zeta", zeta),
                                                 _finite("v_star", v_star), _finite("g", g))
    if np.any(zeta < 0.0) or np.any(v_star <= 0.0) or np.any(g <= 0.0):
        raise ValueError(f"model {model}: zeta must be >= 0, v_star and g > 0; got "
                         f"zeta={zeta!r}, v_star={v_star!r}, g={g!r}")
    shape = speed.shape
    eps, w_slope, tau, tau_slope = _dashpot_state(model, zeta.ravel(),
                                                  (speed / v_star).ravel(), level)
    omega0 = g.ravel() / v_star.ravel()
    return ((eps * speed.ravel()).reshape(shape), w_slope.reshape(shape),
            (tau / omega0).reshape(shape), (tau_slope / g.ravel()).reshape(shape))


# --- the registry -----------------------------------------------------------------------------

def _parameter(name, unit, lower, upper, start, description):
    return LawParameter(name, unit, float(lower), float(upper), float(start), description)


_E0 = ("e0", "", 0.0, 1.0, 0.9, "restitution extrapolated to v = 0")

LAWS = {
    "constant": RestitutionLaw(
        "constant", "ε = e", (_parameter("e", "", 0.0, 1.0, 0.9, "coefficient of restitution"),),
        constant, "—"),
    "linear": RestitutionLaw(
        "linear", "ε = e0 − α·v",
        (_parameter(*_E0), _parameter("alpha", "s/m", -0.2, 0.2, 0.0,
                                      "fall of ε per unit impact speed")),
        linear, "—"),
    "power": RestitutionLaw(
        "power", "ε = a·(v / 1 m/s)^(−b)",
        (_parameter("a", "", 0.0, 1.5, 0.9, "ε at 1 m/s"),
         _parameter("b", "", -0.3, 0.3, 0.0, "exponent of the fall of ε with speed")),
        power, "—"),
    "quadratic": RestitutionLaw(
        "quadratic", "ε = e0 − c·v²",
        (_parameter(*_E0), _parameter("c", "s²/m²", -0.1, 0.1, 0.0,
                                      "fall of ε per squared impact speed")),
        quadratic, "—"),
    "viscoelastic-hertz": RestitutionLaw(
        "viscoelastic-hertz", "ε = 1 − C1·δ + C2·δ² + δ·q(δ), δ = κv^(1/5), q integrated",
        (_parameter("kappa", "s^(1/5)/m^(1/5)", 0.0, 0.2, 0.03,
                    "(3/2)·A·(k/m)^(2/5): viscoelastic damping of a Hertz contact"),),
        viscoelastic_hertz, "Ramírez, Pöschel, Brilliantov, Schwager, PRE 60, 4465 (1999)"),
    "hunt-crossley": RestitutionLaw(
        "hunt-crossley", "ln((1 + χv)/(1 − χvε)) = χv(1 + ε)",
        (_parameter("chi", "s/m", 0.0, 10.0, 0.05, "λ/k: Hunt–Crossley damping per stiffness"),),
        hunt_crossley, "Hunt & Crossley, J. Appl. Mech. 42, 440 (1975)"),
}
"""Every restitution law by name: the ladder's rungs, then the five dashpot models."""

LADDER = tuple(LAWS)
"""Names of the ladder's rungs, simplest first (the dashpot models follow in :data:`LAWS`)."""

for _model in MODELS:
    LAWS[_model] = RestitutionLaw(
        _model, f"ε of dashpot model {_model} at ṽ = v/v*",
        (_parameter("zeta", "", 0.0, 10.0, 0.1, "damping ratio β/ω0"),
         _parameter("v_star", "m/s", 1e-6, 100.0, 1e-3, "speed unit g/ω0")),
        _dashpot_law(_model), "Bartz, sections 3-4")
del _model


def restitution(name, speed, *params):
    """ε of the law `name` at `speed` (m/s): ``LAWS[name](speed, *params)``.

    Raises
    ------
    ValueError
        Unknown law (the message lists the known ones) or bad arguments.
    """
    if name not in LAWS:
        raise ValueError(f"restitution law must be one of {', '.join(map(repr, LAWS))}; "
                         f"got {name!r}")
    return LAWS[name](speed, *params)
