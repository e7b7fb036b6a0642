"""Flight between impacts (gravity, air drag with buoyancy and added mass, incline friction).

The closed forms are checked against direct integration of the equations of motion written
from the forces (weight, buoyancy, drag, added mass), against 40-digit evaluations, and their
slopes against finite differences.
"""

import math

import mpmath
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from dashpot.physics.flight import (
    apex_height,
    drag_constant,
    drag_flight,
    effective_gravity,
    fall_time,
    gravity_flight,
    incline_flight,
    rise_time,
    terminal_speed,
    track_flight,
)

G = 9.81
AIR = 1.2  # kg/m³
# A table-tennis ball (ITTF: 2.7 g, 40 mm) and a heavier, smaller ball.
BALLS = [(2.7e-3, 0.040, 0.45), (0.058, 0.067, 0.5), (1.0e-3, 0.030, 0.47)]


def integrate_ball(speed, mass, diameter, drag_coefficient, air_density=AIR, g=G):
    """Flight of a sphere launched upward, from its forces: (duration, landing speed, rise
    time, apex height), by solve_ivp at rtol 1e-12."""
    volume = math.pi / 6.0 * diameter ** 3
    inertia = mass + 0.5 * air_density * volume  # added mass of a sphere
    weight = (mass - air_density * volume) * g  # weight minus buoyancy
    drag = 0.5 * air_density * drag_coefficient * math.pi * diameter ** 2 / 4.0

    def motion(t, state):
        z, v = state
        return [v, (-weight - drag * v * abs(v)) / inertia]

    def apex(t, state):
        return state[1]

    def landing(t, state):
        return state[0]

    apex.terminal, landing.terminal, landing.direction = True, True, -1.0
    options = dict(method="DOP853", rtol=1e-12, atol=1e-14)
    up = solve_ivp(motion, (0.0, 100.0), [0.0, speed], events=apex, **options)
    top = up.t_events[0][0], up.y_events[0][0]
    down = solve_ivp(motion, (top[0], 200.0), top[1], events=landing, **options)
    return down.t_events[0][0], -down.y_events[0][0][1], top[0], top[1][0]


@pytest.mark.parametrize("mass, diameter, drag_coefficient", BALLS)
@pytest.mark.parametrize("speed", [0.05, 0.7, 2.3, 9.0, 40.0])
def test_drag_closed_forms_match_integrated_flight(mass, diameter, drag_coefficient, speed):
    g_eff = effective_gravity(G, mass, diameter, AIR)
    k_d = drag_constant(mass, diameter, drag_coefficient, AIR)
    duration, landing, rise, height = integrate_ball(speed, mass, diameter, drag_coefficient)
    flight = drag_flight(speed, g_eff, k_d)
    assert flight.duration == pytest.approx(duration, rel=1e-9)
    assert flight.landing_speed == pytest.approx(landing, rel=1e-9)
    assert rise_time(speed, g_eff, k_d) == pytest.approx(rise, rel=1e-9)
    assert fall_time(speed, g_eff, k_d) == pytest.approx(duration - rise, rel=1e-9)
    assert apex_height(speed, g_eff, k_d) == pytest.approx(height, rel=1e-9)


def test_ping_pong_ball_constants():
    # Buoyancy and added mass lower g by about 2 % and v_t is about 9 m/s (issue 13).
    g_eff = effective_gravity(G, 2.7e-3, 0.040, AIR)
    k_d = drag_constant(2.7e-3, 0.040, 0.45, AIR)
    assert 0.97 < g_eff / G < 0.99
    assert 8.0 < terminal_speed(g_eff, k_d) < 10.0
    assert effective_gravity(G, 2.7e-3, 0.040, 0.0) == G
    assert terminal_speed(G, 0.0) == math.inf


@pytest.mark.parametrize("speed, quoted", [(2.3, 0.930), (1.3, 0.950), (0.7, 0.957)])
def test_ping_pong_apparent_interval_ratio(speed, quoted):
    """Constant ε = 0.96 looks like a rising ε: interval ratios from the integrated flight."""
    ball = (2.7e-3, 0.040, 0.45)
    first, landing, _, _ = integrate_ball(speed, *ball)
    second, _, _, _ = integrate_ball(0.96 * landing, *ball)
    assert second / first == pytest.approx(quoted, abs=1e-3)
    g_eff, k_d = effective_gravity(G, 2.7e-3, 0.040, AIR), drag_constant(*ball, AIR)
    closed = drag_flight(0.96 * drag_flight(speed, g_eff, k_d).landing_speed, g_eff, k_d)
    assert closed.duration / drag_flight(speed, g_eff, k_d).duration == pytest.approx(
        second / first, rel=1e-9)


def reference(speed, g, drag):
    """Duration, landing speed and apex height from the closed forms at 40 digits."""
    with mpmath.workdps(40):
        u, g, k = mpmath.mpf(speed), mpmath.mpf(g), mpmath.mpf(drag)
        if k == 0:
            return 2 * u / g, u, u * u / (2 * g)
        vt = mpmath.sqrt(g / k)
        w = u / vt
        return ((vt / g) * (mpmath.atan(w) + mpmath.asinh(w)), u / mpmath.sqrt(1 + w * w),
                mpmath.log1p(w * w) / (2 * k))


@pytest.mark.parametrize("drag", [0.0, 1e-300, 1e-12, 1e-6, 0.125, 3.0, 1e6])
@pytest.mark.parametrize("speed", [0.0, 1e-200, 1e-3, 0.7, 2.3, 50.0, 1e150, 1e300])
def test_drag_forms_keep_their_digits(speed, drag):
    """Small k_d (no cancellation against the gravity limit) and huge speeds (no overflow)."""
    flight = drag_flight(speed, 9.6, drag)
    height = apex_height(speed, 9.6, drag)
    values = [flight.duration, flight.landing_speed, flight.duration_slope,
              flight.landing_slope, height]
    if drag == 0.0 and speed > 1e150:
        assert height == math.inf  # u²/2g is beyond the float range
        values.pop()
    assert all(np.isfinite(values))
    duration, landing, apex = reference(speed, 9.6, drag)
    assert float(flight.duration) == pytest.approx(float(duration), rel=2e-15, abs=1e-320)
    assert float(flight.landing_speed) == pytest.approx(float(landing), rel=2e-15, abs=1e-320)
    if np.isfinite(height):
        assert float(height) == pytest.approx(float(apex), rel=4e-15, abs=1e-320)


def test_zero_drag_is_gravity():
    speeds = np.array([0.0, 0.3, 2.3, 17.0])
    gravity, drag = gravity_flight(speeds, G), drag_flight(speeds, G, 0.0)
    incline = incline_flight(speeds, G, G)
    for law in (drag, incline):
        for name in ("duration", "landing_speed", "duration_slope", "landing_slope"):
            np.testing.assert_allclose(getattr(law, name), getattr(gravity, name), rtol=1e-15)
    np.testing.assert_allclose(gravity.duration, 2.0 * speeds / G, rtol=1e-15)
    # k_d = 1e-12 departs from gravity by its leading term, T = (2u/g)(1 − k_d u²/4g + …),
    # not by rounding noise.
    tiny = drag_flight(speeds, G, 1e-12)
    np.testing.assert_allclose(tiny.duration, 2.0 * speeds / G * (1.0 - 1e-12 * speeds ** 2
                                                                    / (4.0 * G)), rtol=1e-15)


def central_difference(function, speed, step):
    return (function(speed + step) - function(speed - step)) / (2.0 * step)


@pytest.mark.parametrize("speed", [1e-3, 0.7, 2.3, 30.0])
@pytest.mark.parametrize("law, args", [(drag_flight, (9.6, 0.125)), (drag_flight, (9.6, 0.0)),
                                       (drag_flight, (3.0, 20.0)), (gravity_flight, (9.6,)),
                                       (incline_flight, (2.05, 1.96))])
def test_slopes_match_finite_differences(law, args, speed):
    flight = law(speed, *args)
    step = 1e-5 * speed
    duration = central_difference(lambda u: law(u, *args).duration, speed, step)
    landing = central_difference(lambda u: law(u, *args).landing_speed, speed, step)
    assert flight.duration_slope == pytest.approx(duration, rel=1e-8)
    assert flight.landing_slope == pytest.approx(landing, rel=1e-8)


def integrate_cart(speed, up, down):
    """Cart leaving the bumper at `speed`: decelerates at `up` going out, accelerates at
    `down` coming back; (duration, return speed) by solve_ivp with a stop at the turning point."""
    options = dict(method="DOP853", rtol=1e-12, atol=1e-14)

    def stop(t, state):
        return state[1]

    def bumper(t, state):
        return state[0]

    stop.terminal, bumper.terminal, bumper.direction = True, True, -1.0
    out = solve_ivp(lambda t, s: [s[1], -up], (0.0, 100.0), [0.0, speed], events=stop, **options)
    turn = out.t_events[0][0], out.y_events[0][0]
    back = solve_ivp(lambda t, s: [s[1], -down], (turn[0], 200.0), turn[1] * [1.0, 0.0],
                     events=bumper, **options)
    return back.t_events[0][0], -back.y_events[0][0][1]


@pytest.mark.parametrize("speed, up, down", [(0.4, 2.05, 1.96), (0.05, 0.3, 0.1),
                                             (1.2, 2.9, 2.9)])
def test_incline_matches_integrated_motion(speed, up, down):
    duration, landing = integrate_cart(speed, up, down)
    flight = incline_flight(speed, up, down)
    assert flight.duration == pytest.approx(duration, rel=1e-9)
    assert flight.landing_speed == pytest.approx(landing, rel=1e-9)
    # Rolling friction costs speed on every flight: 2-4 % on a real PASCO run (issue 13).
    if down < up:
        assert landing < speed


def test_arrays_broadcast_to_one_shape():
    speeds = np.linspace(0.1, 3.0, 6).reshape(2, 3)
    flight = drag_flight(speeds, 9.6, np.array([0.0, 0.1, 0.2]))
    assert all(getattr(flight, name).shape == (2, 3) for name in
               ("duration", "landing_speed", "duration_slope", "landing_slope"))
    np.testing.assert_allclose(flight.duration[1], drag_flight(speeds[1], 9.6, [0.0, 0.1, 0.2])
                               .duration, rtol=0)


@pytest.mark.parametrize("call, name", [
    (lambda: drag_flight(-1.0, 9.6, 0.1), "speed"),
    (lambda: drag_flight(1.0, 9.6, float("nan")), "drag"),
    (lambda: drag_flight(1.0, 0.0, 0.1), "g"),
    (lambda: incline_flight(1.0, 2.0, 0.0), "down"),
    (lambda: gravity_flight(float("inf"), 9.8), "speed"),
    (lambda: drag_constant(0.0, 0.04, 0.45, 1.2), "mass"),
])
def test_bad_arguments_name_themselves(call, name):
    with pytest.raises(ValueError, match=f"^{name} must"):
        call()


def track_reference(speed, up, down, drag):
    """Duration and landing speed of the track flight at 40 digits, from the textbook steps:
    rise t = atan(w)/√(k a_up) to h = ln(1 + w²)/2k, fall from rest cosh(√(k a_down)t) = e^(kh),
    landing at √(a_down/k)·tanh(√(k a_down)t); without drag, uniform acceleration."""
    with mpmath.workdps(40):
        u, up, down, k = (mpmath.mpf(value) for value in (speed, up, down, drag))
        if k == 0:
            height = u * u / (2 * up)
            fall = mpmath.sqrt(2 * height / down)
            return u / up + fall, down * fall
        w = u * mpmath.sqrt(k / up)
        height = mpmath.log1p(w * w) / (2 * k)
        fall = mpmath.acosh(mpmath.exp(k * height)) / mpmath.sqrt(k * down)
        return (mpmath.atan(w) / mpmath.sqrt(k * up) + fall,
                mpmath.sqrt(down / k) * mpmath.tanh(mpmath.sqrt(k * down) * fall))


@pytest.mark.parametrize("up, down", [(2.95, 2.84), (9.6, 9.6), (1.0, 0.5)])
@pytest.mark.parametrize("drag", [0.0, 1e-9, 0.125, 3.0])
@pytest.mark.parametrize("speed", [1e-3, 0.7, 2.3, 50.0])
def test_track_flight_keeps_its_digits(speed, up, down, drag):
    flight = track_flight(speed, up, down, drag)
    duration, landing = track_reference(speed, up, down, drag)
    assert float(flight.duration) == pytest.approx(float(duration), rel=4e-15)
    assert float(flight.landing_speed) == pytest.approx(float(landing), rel=4e-15)


def test_track_flight_holds_the_drag_and_incline_laws():
    speeds = np.array([0.0, 0.3, 2.3, 17.0])
    for track, other in ((track_flight(speeds, 9.6, 9.6, 0.125), drag_flight(speeds, 9.6, 0.125)),
                         (track_flight(speeds, 2.95, 2.84), incline_flight(speeds, 2.95, 2.84))):
        for name in ("duration", "landing_speed", "duration_slope", "landing_slope"):
            np.testing.assert_allclose(getattr(track, name), getattr(other, name), rtol=1e-15)


@pytest.mark.parametrize("call, name", [
    (lambda: track_flight(-1.0, 2.0, 1.9, 0.0), "speed"),
    (lambda: track_flight(1.0, 0.0, 1.9, 0.0), "up"),
    (lambda: track_flight(1.0, 2.0, -1.0, 0.0), "down"),
    (lambda: track_flight(1.0, 2.0, 1.9, -0.1), "drag"),
])
def test_track_flight_bad_arguments_name_themselves(call, name):
    with pytest.raises(ValueError, match=f"^{name} must"):
        call()
