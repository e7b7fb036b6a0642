"""Argument checks shared by the public functions: one clear ValueError per bad input."""

from __future__ import annotations

import math

import numpy as np

# Physically sensible ranges of the readers' options, in m: wide for any bench apparatus,
# narrow enough to catch a unit slip (a 20 mm flag typed as 20) or a lost sign.
FLAG_LENGTH_RANGE = (0.0, 1.0)  # the flag on a cart is a few cm
GATE_DISTANCE_RANGE = (0.0, 10.0)  # a track is a few m long
BUMPER_POSITION_RANGE = (-20.0, 20.0)  # motion sensors read up to about 10 m
ACCELERATION_RANGE = (0.0, 100.0)  # m/s²: g is 9.8; g_eff on a near-level track ~0.01


def check_model(model, allowed):
    """Return `model` if it is one of `allowed`, else raise a ValueError listing them."""
    if not isinstance(model, str) or model not in allowed:
        raise ValueError(f"model must be one of {', '.join(map(repr, allowed))}; got {model!r}")
    return model


def _as_float_array(name, value):
    try:
        array = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as error:
        raise ValueError(f"{name} must be a real number or array of them; got {value!r}") from error
    if not np.isfinite(array).all():
        raise ValueError(f"{name} must be finite; got a non-finite value in {value!r}")
    return array


def check_nonnegative(name, value):
    """Float array of `value`; ValueError naming `name` unless finite and >= 0."""
    array = _as_float_array(name, value)
    if (array < 0.0).any():
        raise ValueError(f"{name} must be >= 0 (allowed range [0, inf)); got {value!r}")
    return array


def check_positive(name, value):
    """Float array of `value`; ValueError naming `name` unless finite and > 0."""
    array = _as_float_array(name, value)
    if (array <= 0.0).any():
        raise ValueError(f"{name} must be > 0 (allowed range (0, inf)); got {value!r}")
    return array


def range_problem(value, low, high, *, unit="", low_inclusive=False):
    """What is wrong with `value` for the range (low, high] (or [low, high]), or None if fine.

    The text reads after a name: "must be a finite number in (0, 1] m".
    """
    try:
        number = float(value)
    except (TypeError, ValueError):
        return "must be a number"
    above_low = number >= low if low_inclusive else number > low
    if math.isfinite(number) and above_low and number <= high:  # NaN fails every comparison
        return None
    interval = f"{'[' if low_inclusive else '('}{low:g}, {high:g}]".replace("inf]", "inf)")
    return f"must be a finite number in {interval}{' ' + unit if unit else ''}"


def check_range(name, value, low, high, *, unit="", low_inclusive=False):
    """`value` as a float; ValueError naming `name` and the range unless finite and inside it.

    Parameters
    ----------
    name : str
        The argument's name, for the message.
    value : float
        The value given.
    low, high : float
        Bounds of the physically sensible range; `high` is included (``inf``: any finite
        value), `low` only with `low_inclusive` (lengths and masses must be > 0, not >= 0).
    unit : str
        Unit of the value and bounds, for the message ("m", "kg").

    Returns
    -------
    float
    """
    problem = range_problem(value, low, high, unit=unit, low_inclusive=low_inclusive)
    if problem is not None:
        raise ValueError(f"{name} {problem}; got {value!r}")
    return float(value)
