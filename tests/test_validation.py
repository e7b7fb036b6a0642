"""Bad input gets a clear ValueError naming the argument, never a silent NaN."""

import numpy as np
import pytest

import dashpot


@pytest.mark.parametrize("model", ["Ic", "", None, "ia", 3])
def test_unknown_model(model):
    with pytest.raises(ValueError, match="model must be one of 'Ia', 'Ib', 'IIa', 'IIb', 'hybrid'"):
        dashpot.collide(model, 0.1, 1.0)
    with pytest.raises(ValueError, match="model must be one of"):
        dashpot.critical_velocity(model, 0.1)


@pytest.mark.parametrize("zeta", [-1e-3, np.nan, np.inf, [0.1, -0.2], "abc"])
def test_bad_zeta(zeta):
    with pytest.raises(ValueError, match="zeta must be"):
        dashpot.collide("Ib", zeta, 1.0)
    with pytest.raises(ValueError, match="zeta must be"):
        dashpot.critical_velocity("IIb", zeta)


@pytest.mark.parametrize("vtilde", [0.0, -2.0, np.nan, -np.inf, np.inf])
def test_bad_vtilde(vtilde):
    with pytest.raises(ValueError, match=r"vtilde must be"):
        dashpot.collide("hybrid", 0.1, vtilde)


def test_bad_method_and_rtol():
    with pytest.raises(ValueError, match="method must be 'exact' or 'ode'"):
        dashpot.collide("Ia", 0.1, 1.0, method="rk4")
    with pytest.raises(ValueError, match="rtol is only used by method='ode'"):
        dashpot.collide("Ia", 0.1, 1.0, rtol=1e-6)
    with pytest.raises(ValueError, match="rtol must be in"):
        dashpot.collide("Ia", 0.1, 1.0, method="ode", rtol=0.0)


@pytest.mark.parametrize("argument,value", [("mass", -1.0), ("stiffness", 0.0), ("damping", -0.1),
                                            ("mass", np.nan)])
def test_bad_si_parameters(argument, value):
    kwargs = dict(mass=0.5, stiffness=255.0, damping=1.0)
    kwargs[argument] = value
    with pytest.raises(ValueError, match=f"{argument} must be"):
        dashpot.natural_parameters(**kwargs)


@pytest.mark.parametrize("argument,value", [("beta", -1.0), ("omega0", 0.0), ("g", np.inf),
                                            ("v0", -1.0), ("n_max", 0), ("n_max", 2.5),
                                            ("v_min", -1.0)])
def test_bad_sequence_parameters(argument, value):
    kwargs = dict(beta=1.0, omega0=20.0, g=9.81, v0=1.0)
    kwargs[argument] = value
    with pytest.raises(ValueError, match=f"{argument} must be"):
        dashpot.bounce_sequence("Ib", **kwargs)


def test_restitution_outside_unit_interval():
    with pytest.raises(ValueError, match="eps must be"):
        dashpot.contact_from_restitution("Ia", 0.01, 1.2, mass=1.0, v0=1.0, g=9.81)


@pytest.mark.parametrize("value,problem", [
    (-1.0, "must be a finite number in (0, 1] m"), (0.0, "in (0, 1] m"),
    (1.5, "in (0, 1] m"), (float("nan"), "finite"), (float("inf"), "finite"),
    ("2 cm", "must be a number"), (None, "must be a number")])
def test_check_range_names_the_argument_and_the_range(value, problem):
    from dashpot._validation import check_range

    with pytest.raises(ValueError) as caught:
        check_range("flag_length", value, 0.0, 1.0, unit="m")
    message = str(caught.value)
    assert message.startswith("flag_length ") and problem in message
    assert message.endswith(f"got {value!r}")


def test_check_range_bounds_and_an_open_top():
    from dashpot._validation import check_range

    assert check_range("x", "1", 0.0, 1.0) == 1.0  # the top is included
    assert check_range("x", 0, 0.0, 1.0, low_inclusive=True) == 0.0
    assert check_range("x", 1e300, 0.0, float("inf"), low_inclusive=True) == 1e300
    with pytest.raises(ValueError, match=r"in \[0, inf\) s; got inf"):
        check_range("x", float("inf"), 0.0, float("inf"), unit="s", low_inclusive=True)
