"""Argument checks shared by the public functions: one clear ValueError per bad input."""

from __future__ import annotations

import numpy as np


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
    if not np.all(np.isfinite(array)):
        raise ValueError(f"{name} must be finite; got a non-finite value in {value!r}")
    return array


def check_nonnegative(name, value):
    """Float array of `value`; ValueError naming `name` unless finite and >= 0."""
    array = _as_float_array(name, value)
    if np.any(array < 0.0):
        raise ValueError(f"{name} must be >= 0 (allowed range [0, inf)); got {value!r}")
    return array


def check_positive(name, value):
    """Float array of `value`; ValueError naming `name` unless finite and > 0."""
    array = _as_float_array(name, value)
    if np.any(array <= 0.0):
        raise ValueError(f"{name} must be > 0 (allowed range (0, inf)); got {value!r}")
    return array
