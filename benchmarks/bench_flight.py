"""Cost of the flight physics in the deterministic fits: air drag and rolling friction.

One table: CPU time of fitting the generating model (hybrid for the ball, Ib for the cart) at
each accuracy level, on the same train with and without the effect, the speed-up of each level
over the exact one (the baseline: exact solver, lmfit's MINPACK), and the error of the fitted
β against the truth in standard errors.

* ball: a ping-pong-sized ball (2.7 g, 40 mm) with a soft contact (β = 5 1/s, ω0 = 300 rad/s),
  30 impacts from 1.2 m/s, 20 µs timing noise; "with" flies and fits the drag (k_d with the
  scene's C_d prior), "without" is the same ball without a diameter (no drag in truth or fit).
* cart: the paper's cart (Ib) with 1 ms timing and 1 mm/s speed noise on a motion sensor;
  "with" has 0.06 m/s² rolling friction and fits both accelerations (a second fit, kept by
  ΔBIC), "without" is a scene that does not try friction on a frictionless train.

Target: the fast level keeps its >= 10x over exact with the effect on. CPU times are the best
of seven runs after a first call (time.process_time). Run with
``python benchmarks/bench_flight.py``.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
from scipy.integrate import solve_ivp

import dashpot
from dashpot.fit import ACCURACY_LEVELS, fit_model, prepare_data
from dashpot.physics.flight import drag_constant
from dashpot.scene import Known, Scene
from timing import best_cpu

SEED = 20261125
BALL_MASS, BALL_DIAMETER, BALL_BETA, BALL_OMEGA0 = 0.0027, 0.040, 5.0, 300.0
CART_MASS, CART_K, CART_BETA, CART_G, CART_FRICTION = 0.506, 255.0, 1.87, 2.8959, 0.06


def ball(with_drag):
    scene = Scene(mass=Known(BALL_MASS),
                  diameter=Known(BALL_DIAMETER) if with_drag else None)
    g = scene.driving_acceleration
    k_d = float(drag_constant(BALL_MASS, BALL_DIAMETER, 0.45, 1.204)) if with_drag else 0.0
    train = dashpot.bounce_sequence("hybrid", beta=BALL_BETA, omega0=BALL_OMEGA0, g=g, v0=1.2,
                                    n_max=30, drag=k_d)
    noise = np.random.default_rng(SEED).normal(0.0, 2e-5, train.impact_times.size)
    impacts = pd.DataFrame({"time": 0.5 + train.impact_times + noise, "time_uncertainty": 2e-5})
    return prepare_data(impacts, scene), scene, "hybrid", BALL_BETA


def cart(with_friction):
    """The cart simulated by solve_ivp through contact (Ib) and flights with friction."""
    omega0 = math.sqrt(CART_K / CART_MASS)
    friction = CART_FRICTION if with_friction else 0.0

    def contact(_, y):
        return [y[1], -CART_G - 2.0 * CART_BETA * y[1] - omega0 ** 2 * y[0]]

    def release(_, y):
        return y[0]
    release.terminal, release.direction = True, 1
    times, impact, rebound, clock, speed = [], [], [], 0.0, 1.0
    for _ in range(30):
        touch = solve_ivp(contact, (0.0, 50.0 / omega0), [0.0, -speed], events=release,
                          rtol=1e-12, atol=1e-15, first_step=1e-6 / omega0)
        ends = touch.t_events[0][touch.t_events[0] > 0.0]
        if not ends.size:
            break
        times.append(clock)
        impact.append(speed)
        out = touch.y_events[0][-1][1]
        rebound.append(out)
        away, toward = CART_G + friction, CART_G - friction
        # Uniform accelerations: stopping takes out/away, and the cart returns at
        # out·√(toward/away) after back/toward more.
        back = out * math.sqrt(toward / away)
        clock += ends[0] + out / away + back / toward
        speed = back
    rng = np.random.default_rng(SEED)
    n = len(times)
    impacts = pd.DataFrame({
        "time": 1.0 + np.array(times) + rng.normal(0.0, 1e-3, n), "time_uncertainty": 1e-3,
        "impact_speed": np.array(impact) + rng.normal(0.0, 1e-3, n),
        "rebound_speed": np.array(rebound) + rng.normal(0.0, 1e-3, n),
        "speed_uncertainty": 1e-3})
    angle = math.degrees(math.asin(CART_G / 9.80665))
    scene = Scene(mass=Known(CART_MASS), incline_angle=angle, friction=with_friction)
    return prepare_data(impacts, scene), scene, "Ib", CART_BETA


def main():
    print("flight physics in the deterministic fits: CPU ms per fit (best of 7), speed-up over "
          "exact, beta error / SE")
    print(f"{'scene':<24}{'level':<10}{'CPU ms':>8}{'speed-up':>10}{'beta err/SE':>13}")
    print("-" * 65)
    verdicts = []
    for name, make in (("ball, drag", lambda: ball(True)), ("ball, no drag", lambda: ball(False)),
                       ("cart, friction", lambda: cart(True)),
                       ("cart, no friction", lambda: cart(False))):
        data, scene, model, beta = make()
        times = {}
        for level in reversed(ACCURACY_LEVELS):
            fit_model(data, model, scene, accuracy=level)
            times[level], fit = best_cpu(
                lambda level=level: fit_model(data, model, scene, accuracy=level), repeats=7)
            estimate = fit.estimates["beta"]
            print(f"{name:<24}{level:<10}{1e3 * times[level]:8.1f}"
                  f"{times['exact'] / times[level]:9.1f}x"
                  f"{(estimate.value - beta) / estimate.stderr:13.2f}")
        verdicts.append(f"{name}: fast {times['exact'] / times['fast']:.1f}x faster than exact "
                        f"(target >= 10x)")
    for line in verdicts:
        print(line)


if __name__ == "__main__":
    main()
