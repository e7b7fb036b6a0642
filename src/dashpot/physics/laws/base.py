"""What a restitution law is: its parameters, its ε(v) and the hooks a fit may use.

A law is a :class:`RestitutionLaw`: a name, the formula in one line, its parameters
(:class:`LawParameter`: unit, fit bounds, start value), the vectorized function
``function(speed, *params) -> (eps, speed_slope, outside)`` and a reference; optionally the
hooks a fit uses where the law has them (start values from the data, a contact duration, a
prior from the scene, derived quantities) and its place on the selection ladder (the effect it
adds to a simpler rung). Nothing here knows any particular law: the laws are defined in the
modules beside this one and collected in :data:`dashpot.physics.laws.LAWS`.

This module imports nothing of the package, so that every law module can import it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..._validation import check_nonnegative

__all__ = ["Derived", "LawParameter", "Restitution", "RestitutionLaw", "finite", "no_flag",
           "parameter"]


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


def parameter(name, unit, lower, upper, start, description):
    """A :class:`LawParameter` with its bounds and start value as floats."""
    return LawParameter(name, unit, float(lower), float(upper), float(start), description)


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
class Derived:
    """A quantity derived from a law's parameters (ω0 = g/v* of a dashpot model, ...).

    Attributes
    ----------
    name : str
        Name of the estimate.
    unit : str
        SI unit.
    value : float
        Its value at the fitted parameters.
    gradient : dict of str -> float
        ∂value/∂p for each law parameter p it depends on (by name), for linear propagation.
    note : str
        How it is derived (shown with the estimate).
    interval_of : str or None
        A law parameter whose interval bounds map onto this quantity's through `through`
        (a monotone map keeps a profile likelihood's intervals); None: the interval is the
        linearly propagated one.
    through : callable or None
        ``through(bound) -> bound`` of the quantity, for `interval_of` (decreasing maps swap
        the ends: the caller passes the parameter's bounds in the order that gives
        low68, high68, low95, high95).
    decreasing : bool
        Whether `through` is decreasing.
    lower : float
        Physical lower bound of a propagated interval (it is clipped there).
    """

    name: str
    unit: str
    value: float
    gradient: dict
    note: str
    interval_of: str | None = None
    through: Callable | None = None
    decreasing: bool = False
    lower: float = -np.inf


@dataclass(frozen=True)
class RestitutionLaw:
    """A restitution law: ε(v; params) with its metadata and the hooks a fit may use.

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
    start : callable, optional
        ``start(eps, typical_speed) -> dict`` of start values (by parameter name) from the
        restitution of the first flights ``eps`` and a typical impact speed of the train in
        m/s; parameters it leaves out start at their :attr:`LawParameter.start`.
    contact : callable, optional
        For a law with a contact duration (the dashpot models):
        ``contact(speed, *params, g=g, level=level) -> (R, dR/dv, τ, dτ/dv)``, the rebound
        speed and the contact duration in s with their slopes from one evaluation of the
        collision; ``level`` one of "exact", "fast", "standard" (surrogate tables).
    contact_model : str, optional
        The dashpot model (:data:`dashpot.physics.models.MODELS`) whose collision this law is:
        a fit takes its start values from that model's deterministic fits.
    scene_prior : callable, optional
        ``scene_prior(stiffness, mass, g) -> (name, value, sd, note) or None`` with the
        scene's known stiffness and mass (:class:`dashpot.scene.Known` or None) and g in
        m/s²: a parameter the scene fixes (sd None) or gives a Gaussian prior.
    derived : callable, optional
        ``derived(values, g) -> tuple of Derived``, ``values`` the fitted law parameters by
        name: quantities reported beside the parameters.
    effect : str
        What the law adds to its :attr:`simpler` rung on the selection ladder
        (:mod:`dashpot.noise_selection`); "" for the base.
    simpler : str or None
        The law it extends (None for the base of the ladder).
    """

    name: str
    formula: str
    parameters: tuple[LawParameter, ...]
    function: Callable
    reference: str
    start: Callable | None = None
    contact: Callable | None = None
    contact_model: str | None = None
    scene_prior: Callable | None = None
    derived: Callable | None = None
    effect: str = "speed term"
    simpler: str | None = "constant"

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
        params = [finite(p.name, value) for p, value in zip(self.parameters, params)]
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


def finite(name, value):
    """`value` as a float array; ValueError naming `name` where it is not finite."""
    array = np.asarray(value, dtype=float)
    if not np.isfinite(array).all():
        raise ValueError(f"{name} must be finite; got {value!r}")
    return array


def no_flag(shape):
    """No point outside the law's domain: a False array of `shape`."""
    return np.zeros(shape, bool)
