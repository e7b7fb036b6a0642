"""Shared test helpers."""

import numpy as np
import pytest


@pytest.fixture(autouse=True)
def _floating_point_errors_raise():
    """Overflow, division by zero and invalid operations are bugs here; underflow is not."""
    with np.errstate(over="raise", divide="raise", invalid="raise", under="ignore"):
        yield
