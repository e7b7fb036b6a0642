"""A ball's (or cart's) flight between two impacts: gravity, air drag, incline friction.

Each flight law maps the launch (rebound) speed u of one bounce to the flight duration T(u)
and the landing (next impact) speed L(u), with their slopes dT/du and dL/du, which the
noise model's Kalman filter (:mod:`dashpot.likelihood`) needs to carry a speed error from one
bounce to the next. All functions are pure and vectorized: arrays broadcast, same shape out.

===========  ===============================  =========================  ====================
law          acceleration along the motion    duration T(u)              landing speed L(u)
===========  ===============================  =========================  ====================
gravity      −g up, +g down                   2u/g                       u
drag         −g_eff ∓ k_d·v|v|                (v_t/g)(atan w + asinh w)  u/√(1 + w²)
incline      −a_up away, +a_down back         u/a_up + u/√(a_up a_down)  u·√(a_down/a_up)
track        −a_up ∓ k_d·v|v| away, back      see :func:`track_flight`   see there
===========  ===============================  =========================  ====================

with w = u/v_t and v_t = √(g_eff/k_d) the terminal speed (in the drag row g is g_eff). The
fits' flight is the track law with the effects of :mod:`dashpot.physics.effects` entered into
its coefficients (one module per effect, a registry of them).

Drag: a sphere of mass m and volume V in air of density ρ feels its weight, the buoyancy ρVg,
and the quadratic drag ½ρC_d A v², and moves the air around it, which adds C_m ρV to its
inertia (C_m = 1/2 for a sphere in potential flow [2]_). Divided by m_eff = m + C_m ρV,

    dv/dt = −g_eff − k_d·v|v|,   g_eff = g(1 − ρ/ρ_ball)/(1 + C_m ρ/ρ_ball),
    k_d = ρ C_d A / (2 m_eff),

(v positive upward). Rising from u, dv/dt = −g(1 + v²/v_t²) stops after
t_up = (v_t/g)·atan(u/v_t) at the height h = (v_t²/2g)·ln(1 + u²/v_t²). Falling from rest,
v = v_t·tanh(gt/v_t) and the distance fallen is (v_t²/g)·ln cosh(gt/v_t); equating it to h gives
cosh(g t_down/v_t) = √(1 + w²), i.e. t_down = (v_t/g)·asinh(w), and the landing speed
v_t·tanh(asinh w) = u/√(1 + w²) [1]_. Its slopes are dT/du = (1/(1 + w²) + 1/√(1 + w²))/g and
dL/du = (1 + w²)^(−3/2). For a ping-pong ball (2.7 g, 40 mm, C_d 0.45, air 1.2 kg/m³) v_t is
about 8.8 m/s and buoyancy with added mass lower g_eff by 2.2 %.

Incline: a cart rolling on a track tilted by θ with rolling friction μ decelerates at
a_up = g(sin θ + μ cos θ) while it moves away from the bumper and accelerates at
a_down = g(sin θ − μ cos θ) on its way back. It stops after u/a_up at the distance u²/2a_up and
returns to the bumper at √(2 a_down · u²/2a_up) = u√(a_down/a_up), taking L(u)/a_down more [3]_.

Track (both at once, the law the fits use): moving away against −a_up − k_d·v², the body
stops after t_up = atan(w)/√(k_d a_up) at h = ln(1 + w²)/(2k_d), now with w = u√(k_d/a_up);
falling back from rest under a_down − k_d·v², cosh(√(k_d a_down)·t) = e^(k_d h) = √(1 + w²)
gives t_down = asinh(w)/√(k_d a_down) and the landing speed
√(a_down/k_d)·tanh(asinh w) = u√(a_down/a_up)/√(1 + w²) [1]_. With a_up = a_down = g it is the
drag row, with k_d = 0 the incline row, and with both the gravity row.

All functions take SI units (m/s, m/s², 1/m, s), or any consistent set: in the dimensionless
units of :mod:`dashpot.physics.models` (speed in v* = g/ω0, time in 1/ω0) g is 1 and k_d is
multiplied by g/ω0².

Numerics: the drag forms are written with atan(w)/w, asinh(w)/w, log1p(w²)/w² and hypot(1, w),
which are accurate to a few ulp for every w ≥ 0 without series; no expression divides by k_d,
so k_d = 0 gives the gravity law exactly and k_d → 0 approaches it smoothly, and huge speeds
neither overflow nor give NaN.

References
----------
.. [1] P. Timmerman and J. P. van der Weele, "On the rise and fall of a ball with linear or
   quadratic drag", Am. J. Phys. 67, 538-546 (1999); and B. L. Lindemuth, "The effect of air
   resistance on falling balls", Am. J. Phys. 39, 757-759 (1971).
.. [2] L. D. Landau and E. M. Lifshitz, *Fluid Mechanics*, 2nd ed., Pergamon (1987), §11
   (added mass of a sphere: half the displaced fluid's mass).
.. [3] S. P. Bartz, "Coefficient of restitution of a linear dashpot on a rigid surface",
   section "Modeling experimental data" (carts on an inclined track, g_eff = g sin θ).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .._validation import check_nonnegative, check_positive

__all__ = ["Flight", "apex_height", "drag_constant", "drag_flight", "effective_gravity",
           "fall_time", "gravity_flight", "incline_flight", "rise_time", "terminal_speed",
           "track_flight"]

SPHERE_ADDED_MASS = 0.5
"""Added-mass coefficient C_m of a sphere in potential flow (Landau & Lifshitz §11)."""


@dataclass(frozen=True)
class Flight:
    """One flight between impacts, per launch speed (arrays broadcast to one shape).

    Attributes
    ----------
    duration : ndarray
        Time from launch to landing T(u) in s.
    landing_speed : ndarray
        Speed at landing L(u) in m/s (the next impact speed).
    duration_slope : ndarray
        dT/du in s²/m.
    landing_slope : ndarray
        dL/du (dimensionless).
    """

    duration: np.ndarray
    landing_speed: np.ndarray
    duration_slope: np.ndarray
    landing_slope: np.ndarray


def effective_gravity(g, mass, diameter, air_density, added_mass=SPHERE_ADDED_MASS):
    """Gravity felt by a ball in air, with buoyancy and added mass: g(1 − ρ/ρ_b)/(1 + C_m ρ/ρ_b).

    Parameters
    ----------
    g : float or ndarray
        Gravitational acceleration in m/s².
    mass : float or ndarray
        Ball mass in kg.
    diameter : float or ndarray
        Ball diameter in m.
    air_density : float or ndarray
        Density of the air ρ in kg/m³ (0: vacuum, g_eff = g).
    added_mass : float
        Added-mass coefficient C_m (1/2 for a sphere).

    Returns
    -------
    ndarray
        g_eff in m/s²; ≤ 0 where the ball is no denser than the air (it does not fall back).
    """
    g = check_positive("g", g)
    mass, volume = _mass_and_volume(mass, diameter)
    displaced = check_nonnegative("air_density", air_density) * volume
    return g * (mass - displaced) / (mass + added_mass * displaced)


def drag_constant(mass, diameter, drag_coefficient, air_density, added_mass=SPHERE_ADDED_MASS):
    """Quadratic-drag constant k_d = ρ C_d A / (2 m_eff) of a sphere, in 1/m.

    Parameters
    ----------
    mass : float or ndarray
        Ball mass in kg.
    diameter : float or ndarray
        Ball diameter in m.
    drag_coefficient : float or ndarray
        Drag coefficient C_d (about 0.45 for a ball at Reynolds numbers 10³-10⁵).
    air_density : float or ndarray
        ρ in kg/m³.
    added_mass : float
        Added-mass coefficient C_m of the inertia m_eff = m + C_m ρ V.

    Returns
    -------
    ndarray
        k_d in 1/m: the deceleration by drag is k_d·v².
    """
    drag_coefficient = check_nonnegative("drag_coefficient", drag_coefficient)
    air_density = check_nonnegative("air_density", air_density)
    mass, volume = _mass_and_volume(mass, diameter)
    effective_mass = mass + added_mass * air_density * volume
    area = 0.25 * math.pi * np.asarray(diameter, dtype=float) ** 2
    return air_density * drag_coefficient * area / (2.0 * effective_mass)


def _mass_and_volume(mass, diameter):
    return check_positive("mass", mass), math.pi / 6.0 * check_positive("diameter", diameter) ** 3


def terminal_speed(g, drag):
    """Terminal speed v_t = √(g/k_d) in m/s (inf without drag).

    Parameters
    ----------
    g : float or ndarray
        Effective gravity g_eff in m/s².
    drag : float or ndarray
        Drag constant k_d in 1/m (>= 0).
    """
    g, drag = _check_drag(g, drag)
    with np.errstate(divide="ignore"):
        return np.sqrt(g / drag)


def gravity_flight(speed, g):
    """Flight under gravity alone: T = 2u/g, L = u.

    Parameters
    ----------
    speed : float or ndarray
        Launch speed u in m/s (>= 0).
    g : float or ndarray
        Acceleration g (or g_eff = g sin θ along a frictionless incline) in m/s².

    Returns
    -------
    Flight
    """
    speed = check_nonnegative("speed", speed)
    g = check_positive("g", g)
    speed, g = np.broadcast_arrays(speed, g)
    return Flight(duration=2.0 * speed / g, landing_speed=speed.copy(),
                  duration_slope=2.0 / g, landing_slope=np.ones_like(speed))


def drag_flight(speed, g, drag):
    """Flight under gravity and quadratic air drag (closed forms; see the module notes).

    Parameters
    ----------
    speed : float or ndarray
        Launch speed u in m/s (>= 0).
    g : float or ndarray
        Effective gravity g_eff in m/s² (:func:`effective_gravity`).
    drag : float or ndarray
        Drag constant k_d in 1/m (:func:`drag_constant`); 0 gives :func:`gravity_flight`.

    Returns
    -------
    Flight
        T = (u/g)(atan w/w + asinh w/w), L = u/√(1 + w²), dT/du = (1/(1 + w²) + 1/√(1 + w²))/g,
        dL/du = (1 + w²)^(−3/2), with w = u√(k_d/g).
    """
    speed, g, w = _drag_arguments(speed, g, drag)
    inverse_root = 1.0 / np.hypot(1.0, w)  # 1/√(1 + w²), no overflow at huge w
    duration = speed / g * (_ratio(np.arctan, w) + _ratio(np.arcsinh, w))
    return Flight(duration=duration, landing_speed=speed * inverse_root,
                  duration_slope=(inverse_root ** 2 + inverse_root) / g,
                  landing_slope=inverse_root ** 3)


def rise_time(speed, g, drag):
    """Time to the apex, (v_t/g)·atan(u/v_t), in s (u/g without drag).

    Parameters
    ----------
    speed, g, drag : float or ndarray
        Launch speed u in m/s, effective gravity in m/s², drag constant k_d in 1/m.
    """
    speed, g, w = _drag_arguments(speed, g, drag)
    return speed / g * _ratio(np.arctan, w)


def fall_time(speed, g, drag):
    """Time from the apex back to the launch height, (v_t/g)·asinh(u/v_t), in s.

    Parameters
    ----------
    speed, g, drag : float or ndarray
        Launch speed u in m/s, effective gravity in m/s², drag constant k_d in 1/m.
    """
    speed, g, w = _drag_arguments(speed, g, drag)
    return speed / g * _ratio(np.arcsinh, w)


def apex_height(speed, g, drag):
    """Apex height above launch, (v_t²/2g)·ln(1 + u²/v_t²) = ln(1 + k_d u²/g)/(2k_d), in m.

    Parameters
    ----------
    speed, g, drag : float or ndarray
        Launch speed u in m/s, effective gravity in m/s², drag constant k_d in 1/m.

    Returns
    -------
    ndarray
        Height in m; inf where u²/2g exceeds the float range (no drag, u > 1e154 m/s).
    """
    speed, g, w, drag = _drag_arguments(speed, g, drag, with_drag=True)
    small = w < 1.0
    ws, us = np.where(small, w, 1.0), np.where(small, speed, 0.0)
    # log1p(w²)/w² → 1 smoothly as w → 0 (k_d → 0); for w ≥ 1 (so k_d > 0) the logarithm is
    # split to avoid w² overflowing at huge speeds.
    with np.errstate(over="ignore"):  # u²/2g beyond the float range (no drag): inf
        near = 0.5 * us * (us / g) * _ratio(np.log1p, ws * ws)
    wl = np.where(small, 1.0, w)
    far = (np.log(wl) + 0.5 * np.log1p((1.0 / wl) ** 2)) / np.where(small, 1.0, drag)
    return np.where(small, near, far)


def incline_flight(speed, up, down):
    """Flight of a cart on an incline with rolling friction: away at −a_up, back at +a_down.

    Parameters
    ----------
    speed : float or ndarray
        Speed u leaving the bumper in m/s (>= 0).
    up : float or ndarray
        Deceleration a_up while moving away from the bumper in m/s² (g sin θ + friction).
    down : float or ndarray
        Acceleration a_down while returning to the bumper in m/s² (g sin θ − friction).

    Returns
    -------
    Flight
        T = u/a_up + u/√(a_up a_down), L = u√(a_down/a_up); both linear in u.
    """
    speed = check_nonnegative("speed", speed)
    up = check_positive("up", up)
    down = check_positive("down", down)
    speed, up, down = np.broadcast_arrays(speed, up, down)
    duration_slope = 1.0 / up + 1.0 / np.sqrt(up * down)
    landing_slope = np.sqrt(down / up)
    return Flight(duration=speed * duration_slope, landing_speed=speed * landing_slope,
                  duration_slope=duration_slope, landing_slope=landing_slope)


def track_flight(speed, up, down, drag=0.0):
    """Flight away from the surface and back under two accelerations and quadratic drag.

    Parameters
    ----------
    speed : float or ndarray
        Launch speed u in m/s (>= 0).
    up : float or ndarray
        Deceleration a_up while moving away from the surface in m/s² (> 0): g_eff on a
        ball, g sin θ + friction on a cart.
    down : float or ndarray
        Acceleration a_down on the way back in m/s² (> 0): g_eff, or g sin θ − friction.
    drag : float or ndarray, default 0
        Drag constant k_d in 1/m (>= 0).

    Returns
    -------
    Flight
        T = (u/a_up)·atan(w)/w + (u/√(a_up a_down))·asinh(w)/w, L = u√(a_down/a_up)/√(1 + w²),
        dT/du = 1/(a_up(1 + w²)) + 1/(√(a_up a_down)·√(1 + w²)),
        dL/du = √(a_down/a_up)·(1 + w²)^(−3/2), with w = u√(k_d/a_up) (module notes).
    """
    speed = check_nonnegative("speed", speed)
    up = check_positive("up", up)
    down = check_positive("down", down)
    drag = check_nonnegative("drag", drag)
    speed, up, down, drag = np.broadcast_arrays(speed, up, down, drag)
    duration, landing_speed, duration_slope, landing_slope = _track(speed, up, down, drag)
    return Flight(duration=duration, landing_speed=landing_speed,
                  duration_slope=duration_slope, landing_slope=landing_slope)


def _track(speed, up, down, drag):
    """Unchecked :func:`track_flight` (arrays broadcast): T, L, dT/du, dL/du.

    For the train solvers, which call it on checked, dimensionless arrays many times a fit.
    """
    w = speed * np.sqrt(drag / up)
    inverse_root = 1.0 / np.hypot(1.0, w)  # 1/√(1 + w²), no overflow at huge w
    back = 1.0 / np.sqrt(up * down)
    ratio = np.sqrt(down / up)
    duration = speed * (_ratio(np.arctan, w) / up + _ratio(np.arcsinh, w) * back)
    return (duration, speed * ratio * inverse_root,
            inverse_root ** 2 / up + inverse_root * back, ratio * inverse_root ** 3)


def _check_drag(g, drag):
    return check_positive("g", g), check_nonnegative("drag", drag)


def _drag_arguments(speed, g, drag, with_drag=False):
    """Checked, broadcast (u, g, w = u√(k_d/g)[, k_d]); w = 0 exactly where k_d = 0."""
    speed = check_nonnegative("speed", speed)
    g, drag = _check_drag(g, drag)
    speed, g, drag = np.broadcast_arrays(speed, g, drag)
    w = speed * np.sqrt(drag / g)
    return (speed, g, w, drag) if with_drag else (speed, g, w)


def _ratio(function, w):
    """function(w)/w with its limit 1 at w = 0 (atan, asinh, log1p are all ≈ w there)."""
    positive = w > 0.0
    safe = np.where(positive, w, 1.0)
    return np.where(positive, function(safe) / safe, 1.0)
