"""A scene: one recording plus what is known of the apparatus that made it.

Known quantities are fixed in the fits (or enter as priors when given with an uncertainty);
unknown ones are fitted; effects a scene does not declare are not modelled. A scene is read from
a ``scene.yaml`` (documented in ``config/README.md``) or built from a mapping; both are checked
against the JSON schema shipped with the package, and a bad file gives one
:class:`~dashpot.errors.InputError` line naming it.

Air drag is modelled only for a scene that gives the ball's mass and diameter: quadratic drag
k_d·v² with k_d = ρ C_d A/(2 m_eff), and gravity lowered by buoyancy and added mass
(:mod:`dashpot.physics.flight`). Without both, drag and a speed-dependent ε cannot be told apart
from impact times alone, and nothing is modelled.

References
----------
.. [1] S. P. Bartz, "Coefficient of restitution of a linear dashpot on a rigid surface":
   the cart on an incline, g_eff = g·sin θ along the track.
.. [2] H. Schlichting, *Boundary-Layer Theory*, McGraw-Hill (1955 and later editions), the
   drag coefficient of a smooth sphere against the Reynolds number (the standard drag curve):
   C_d ≈ 0.48 at Re = 10³, 0.39-0.41 at Re = 3·10³-10⁴, 0.44-0.48 at 1.5·10⁴-10⁵; fitted in
   F. A. Morrison, "Data correlation for drag coefficient for sphere", Michigan Technological
   University (2010). A ping-pong ball at 0.5-3 m/s has Re = vd/ν ≈ 1.3·10³-8·10³.
.. [3] ISO 2533:1975, Standard Atmosphere: dry air at 20 °C and 101 325 Pa has ρ = 1.204 kg/m³.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields, replace
from functools import lru_cache
from importlib.resources import files
from pathlib import Path

import numpy as np

from .errors import InputError
from .physics.flight import drag_constant, effective_gravity
from .physics.models import MODELS
from .safe_yaml import load_yaml

__all__ = ["AirDrag", "Known", "Scene", "load_scene", "scene_from_mapping", "STANDARD_GRAVITY",
           "DEFAULT_AIR_DENSITY", "DEFAULT_DRAG_COEFFICIENT"]

STANDARD_GRAVITY = 9.80665  # m/s², conventional value (CGPM 1901)
MIN_DRIVING_ACCELERATION = 1e-3  # m/s², as the schema's g_eff: a track level to 1e-4 rad
INCLINE_ANGLE_UNCERTAINTY = 0.5
"""1σ of a stated incline angle in degrees, where the fits measure g_eff from the motion: a
track's tilt read off a protractor or a phone's inclinometer is good to about half a degree
(real cart runs measured g_eff 4 % off the stated angle, 0.5° at 12°)."""
CART_SENSORS = ("motion_sensor", "photogate")


@dataclass(frozen=True)
class Known:
    """A quantity the scene knows: its value and, for a prior, its 1σ uncertainty (same unit).

    ``uncertainty`` None means the value is taken as exact and the parameter is fixed.
    """

    value: float
    uncertainty: float | None = None


DEFAULT_AIR_DENSITY = Known(1.204)
"""Density of dry air at 20 °C and sea-level pressure in kg/m³ [3]_, taken as exact."""
DEFAULT_DRAG_COEFFICIENT = Known(0.45, 0.05)
"""Drag coefficient prior of a smooth sphere at Re ≈ 10³-10⁴ [2]_."""


@dataclass(frozen=True)
class AirDrag:
    """Quadratic air drag on a scene's ball, with 1σ uncertainties from the scene's priors.

    Attributes
    ----------
    drag_constant : Known
        k_d = ρ C_d A/(2 m_eff) in 1/m: the drag deceleration is k_d·v².
    effective_gravity : Known
        g_eff in m/s²: the scene's driving acceleration lowered by buoyancy and added mass
        (or the scene's measured ``g_eff``, taken as it is).
    correlation : float
        Correlation of the two (both depend on the mass, diameter and air density); 0 where
        either is exact.
    """

    drag_constant: Known
    effective_gravity: Known
    correlation: float = 0.0

    @property
    def terminal_speed(self):
        """Terminal speed √(g_eff/k_d) in m/s."""
        return math.sqrt(self.effective_gravity.value / self.drag_constant.value)


def _propagate(function, knowns):
    """Values of ``function(*values)`` and their covariance, to first order in the priors.

    Parameters
    ----------
    function : callable
        Maps the values of `knowns` (floats) to a sequence of floats.
    knowns : sequence of Known
        Inputs; exact ones (uncertainty None) do not contribute.

    Returns
    -------
    values : ndarray
    covariance : ndarray
        J·diag(σ²)·Jᵀ with the Jacobian J from central differences (step 10⁻⁶ of each value,
        relative error about 10⁻¹⁰, far below what an uncertainty needs).
    """
    centre = [known.value for known in knowns]
    values = np.asarray(function(*centre), dtype=float)
    covariance = np.zeros((values.size, values.size))
    for index, known in enumerate(knowns):
        if not known.uncertainty:
            continue
        step = 1e-6 * known.value
        high, low = list(centre), list(centre)
        high[index] += step
        low[index] -= step
        slope = (np.asarray(function(*high)) - np.asarray(function(*low))) / (2.0 * step)
        covariance += np.outer(slope, slope) * known.uncertainty ** 2
    return values, covariance


def _known(value, variance):
    return Known(float(value), float(math.sqrt(variance)) if variance > 0 else None)


@dataclass(frozen=True)
class Scene:
    """What is known of one recording's apparatus (SI units).

    Attributes
    ----------
    name : str
        Scene name (used for output files).
    sensor : str or None
        Reader kind ("audio", "phyphox", "timestamps", "motion_sensor", "photogate"); None
        lets the reader choose from the file.
    recording : pathlib.Path or None
        The recording, resolved against the scene file's folder.
    models : tuple of str
        Contact models to fit.
    gravity : float
        Local gravitational acceleration g in m/s².
    incline_angle : float or None
        Incline of the track in degrees (cart scenes); the driving acceleration is g·sin θ.
    g_eff : float or None
        Driving acceleration along the motion in m/s², if measured directly (overrides the
        incline).
    mass : Known or None
        Mass of the ball or cart in kg (turns ω0 into k and β into γ).
    stiffness : Known or None
        Contact stiffness k in N/m.
    first_impact_speed : Known or None
        Speed of the first impact in m/s.
    drop_height : Known or None
        Height of the drop above the first impact in m (gives the first impact speed √(2gh)).
    timing_resolution : float or None
        Resolution of the impact times in s (a sample period, a clock tick); sets the timing
        uncertainty where the recording does not give one, and the solver tolerance.
    reader : dict
        Options for the reader (flag_length, gate_distance, bumper_position, unit, track).
    accuracy : str
        Numerical accuracy level of the fits ("auto", "fast", "standard", "exact").
    noise : bool or "auto"
        Also fit under the noise model (bounce-to-bounce scatter and timing jitter): the
        restitution-law ladder and the models, with their own selection. "auto" (default):
        only where every deterministic fit misses the impact times' stated uncertainties
        (:func:`dashpot.fit.fit_scene`); True: always; False: never.
    diameter : Known or None
        Diameter of the ball in m; with ``mass`` it turns on air drag (:attr:`drag`).
    air_density : Known or None
        Density of the air in kg/m³ (None: :data:`DEFAULT_AIR_DENSITY` where drag is modelled).
    drag_coefficient : Known or None
        Drag coefficient C_d of the ball (None: the prior :data:`DEFAULT_DRAG_COEFFICIENT`).
    contact_time : Known or None
        Duration of the first contact in s (e.g. 0.7 ± 0.3 ms for a table-tennis ball): a
        prior on ω0 = π/τ in the fits (:func:`dashpot.fit.fit_model`).
    friction : bool or None
        Whether the fits try rolling friction in flight (two accelerations, away from and
        toward the bumper; kept only where the data support it). None: tried for cart scenes
        (an incline angle, or a motion sensor's or photogate's recording).
    uncertainty : tuple of str
        Methods for the intervals of β (:func:`dashpot.fit.fit_model`): "covariance" (always),
        "profile" (profile likelihood), "posterior" (emcee sampling); default covariance only.
    """

    name: str = "scene"
    sensor: str | None = None
    recording: Path | None = None
    models: tuple = MODELS
    gravity: float = STANDARD_GRAVITY
    incline_angle: float | None = None
    g_eff: float | None = None
    mass: Known | None = None
    stiffness: Known | None = None
    first_impact_speed: Known | None = None
    drop_height: Known | None = None
    timing_resolution: float | None = None
    reader: dict = field(default_factory=dict)
    accuracy: str = "auto"
    noise: bool | str = "auto"
    diameter: Known | None = None
    air_density: Known | None = None
    drag_coefficient: Known | None = None
    contact_time: Known | None = None
    friction: bool | None = None
    uncertainty: tuple = ("covariance",)

    @property
    def _acceleration_without_air(self):
        """g_eff as given, else g·sin θ, else g [1]_, in m/s² (no buoyancy)."""
        if self.g_eff is not None:
            return self.g_eff
        if self.incline_angle is not None:
            return self.gravity * math.sin(math.radians(self.incline_angle))
        return self.gravity

    @property
    def driving_acceleration(self):
        """Acceleration back towards the surface in m/s²: g_eff, else g·sin θ, else g [1]_;
        lowered by buoyancy and added mass where the scene models drag (unless g_eff is
        given: a measured g_eff already holds them)."""
        if self.g_eff is None and self.needs_drag:
            return self._drag_values(*(known.value for known in self._drag_inputs()))[1]
        return self._acceleration_without_air

    @property
    def tries_friction(self):
        """Whether the fits try rolling friction in flight (see ``friction``)."""
        if self.friction is not None:
            return self.friction
        return self.incline_angle is not None or self.sensor in CART_SENSORS

    @property
    def flight_acceleration(self):
        """What is known of the mean acceleration of the flights g_eff, in m/s² (Known).

        The stated g_eff, exact; else g·sin θ from the incline angle with the uncertainty of
        :data:`INCLINE_ANGLE_UNCERTAINTY` carried to it (g·cos θ·δθ): a prior the motion data
        refine where a fit measures the flight's accelerations; else the driving
        acceleration, exact.
        """
        if self.g_eff is None and self.incline_angle is not None:
            angle = math.radians(self.incline_angle)
            return Known(self.driving_acceleration, self.gravity * math.cos(angle)
                         * math.radians(INCLINE_ANGLE_UNCERTAINTY))
        return Known(self.driving_acceleration)

    @property
    def needs_drag(self):
        """Whether air drag is modelled: only when the scene gives the ball's mass and
        diameter."""
        return self.mass is not None and self.diameter is not None

    def _drag_inputs(self):
        return (self.mass, self.diameter, self.drag_coefficient or DEFAULT_DRAG_COEFFICIENT,
                self.air_density or DEFAULT_AIR_DENSITY)

    def _drag_values(self, mass, diameter, drag_coefficient, air_density):
        """(k_d in 1/m, g_eff in m/s²) of a ball, from :mod:`dashpot.physics.flight`."""
        k_d = drag_constant(mass, diameter, drag_coefficient, air_density)
        if self.g_eff is not None:  # measured: buoyancy and added mass are in it
            return float(k_d), self.g_eff
        g = effective_gravity(self._acceleration_without_air, mass, diameter, air_density)
        return float(k_d), float(g)

    @property
    def drag(self):
        """Air drag on the ball (:class:`AirDrag`), or None if the scene does not model it.

        k_d = ρ C_d A/(2(m + ρV/2)) and g_eff = g(m − ρV)/(m + ρV/2) (buoyancy and added mass
        of a sphere, :mod:`dashpot.physics.flight`), with 1σ uncertainties carried to first
        order from the priors of the mass, diameter, drag coefficient (default 0.45 ± 0.05
        [2]_) and air density (default 1.204 kg/m³ [3]_).
        """
        if not self.needs_drag:
            return None
        values, covariance = _propagate(self._drag_values, self._drag_inputs())
        spread = np.sqrt(np.diag(covariance))
        correlation = (covariance[0, 1] / (spread[0] * spread[1]) if np.all(spread > 0)
                       else 0.0)
        return AirDrag(drag_constant=_known(values[0], covariance[0, 0]),
                       effective_gravity=_known(values[1], covariance[1, 1]),
                       correlation=float(correlation))

    @property
    def known_impact_speed(self):
        """Known first impact speed (m/s) from the scene, or None: √(2 g_eff h) for a drop,
        √((g_eff/k_d)(1 − e^(−2 k_d h))) with air drag."""
        if self.first_impact_speed is not None:
            return self.first_impact_speed
        if self.drop_height is None:
            return None
        if self.needs_drag:
            # Falling from rest, v² = v_t²(1 − e^(−2 k_d h)); the priors of the drop height and
            # of the ball's drag all carry to the speed.
            def speed_of(height, *ball):
                k_d, g = self._drag_values(*ball)
                return [math.sqrt(-g / k_d * math.expm1(-2.0 * k_d * height))]

            values, covariance = _propagate(speed_of, (self.drop_height, *self._drag_inputs()))
            return _known(values[0], covariance[0, 0])
        g = self.driving_acceleration
        speed = math.sqrt(2.0 * g * self.drop_height.value)
        spread = self.drop_height.uncertainty
        # dv/dh = g/v: the height's uncertainty carried to the speed.
        return Known(speed, None if spread is None else g * spread / speed)

    def as_dict(self):
        """Plain mapping of the scene (for provenance records); the drag keys and ``drag``
        (k_d, g_eff) only where the scene models drag."""
        out = {}
        for item in fields(self):
            value = getattr(self, item.name)
            if (item.name == "noise" and value == "auto") or (item.name == "friction"
                                                        and value is None) or (
                    item.name == "uncertainty" and tuple(value) == ("covariance",)):
                continue  # recorded only where asked for: the default scene's record unchanged
            if item.name in _DRAG_KEYS:
                if not self.needs_drag:
                    continue
                value = value or {"air_density": DEFAULT_AIR_DENSITY,
                                  "drag_coefficient": DEFAULT_DRAG_COEFFICIENT}[item.name]
            if isinstance(value, Known):
                value = {"value": value.value, "uncertainty": value.uncertainty}
            elif isinstance(value, Path):
                value = str(value)
            elif isinstance(value, tuple):
                value = list(value)
            out[item.name] = value
        out["driving_acceleration"] = self.driving_acceleration
        drag = self.drag
        if drag is not None:
            out["drag"] = {name: {"value": known.value, "uncertainty": known.uncertainty}
                           for name, known in (("drag_constant", drag.drag_constant),
                                               ("effective_gravity", drag.effective_gravity))}
        return out


_DRAG_KEYS = ("diameter", "air_density", "drag_coefficient")
_KNOWN_KEYS = ("mass", "stiffness", "first_impact_speed", "drop_height",
               "contact_time") + _DRAG_KEYS


@lru_cache(maxsize=1)
def _validator():
    """The scene schema's validator, built once per process: loading the schema and checking
    it cost ten times a scene's validation, and a chunk of the workflow reads many scenes."""
    import jsonschema
    import yaml

    schema = yaml.safe_load(files("dashpot").joinpath("scene.schema.yaml").read_text())
    validator_class = jsonschema.validators.validator_for(schema)
    validator_class.check_schema(schema)
    return validator_class(schema)


def _non_finite(value, where=()):
    """Path of the first NaN or infinite number in a nested mapping/list, else None."""
    if isinstance(value, float) and not math.isfinite(value):
        return where
    items = value.items() if isinstance(value, dict) else (
        enumerate(value) if isinstance(value, list) else ())
    for key, item in items:
        found = _non_finite(item, where + (key,))
        if found is not None:
            return found
    return None


def scene_from_mapping(mapping, *, source="scene", base=None):
    """Scene from a mapping with the keys of ``scene.yaml``.

    Parameters
    ----------
    mapping : dict
        Keys as documented in ``config/README.md``; validated against the package's schema.
    source : str or os.PathLike
        Where the mapping came from, for error messages.
    base : str or os.PathLike, optional
        Folder against which a relative ``recording`` path is resolved.

    Returns
    -------
    Scene

    Raises
    ------
    InputError
        The mapping does not follow the schema (which also bounds every number to a
        physically sensible range), or its values are inconsistent.
    """
    from jsonschema.exceptions import best_match

    mapping = dict(mapping or {})
    # As jsonschema.validate reports it: the most relevant of the errors.
    error = best_match(_validator().iter_errors(mapping))
    if error is not None:
        where = "/".join(str(part) for part in error.absolute_path) or "top level"
        message = error.message
        if len(message) > 200:  # the schema quotes the value: a 5000-digit number, a list
            message = f"{message[:100]}…{message[-60:]}"
        raise InputError(source, f"invalid scene ({where}: {message})") from None
    bad = _non_finite(mapping)
    if bad is not None:
        where = "/".join(str(part) for part in bad)
        raise InputError(source, f"invalid scene ({where}: not a finite number)")
    apparatus = dict(mapping.get("apparatus", {}))
    kwargs = {}
    for key in _KNOWN_KEYS:
        value = apparatus.pop(key, None)
        if isinstance(value, dict):
            spread = value.get("uncertainty")
            kwargs[key] = Known(float(value["value"]), None if spread is None else float(spread))
        elif value is not None:
            kwargs[key] = Known(float(value))
    for key in ("gravity", "incline_angle", "g_eff"):
        if apparatus.get(key) is not None:
            kwargs[key] = float(apparatus.pop(key))
    if "first_impact_speed" in kwargs and "drop_height" in kwargs:
        raise InputError(source, "give either apparatus.first_impact_speed or "
                                 "apparatus.drop_height, not both")
    if "contact_time" in kwargs and "stiffness" in kwargs:
        raise InputError(source, "give either apparatus.contact_time or apparatus.stiffness "
                                 "(both set omega0), not both")
    recording = mapping.get("recording")
    if recording is not None:
        recording = Path(base or ".") / recording
    models = tuple(mapping.get("models", MODELS))
    scene = Scene(name=str(mapping.get("name", Path(str(source)).parent.name or "scene")),
                  sensor=mapping.get("sensor"), recording=recording, models=models,
                  timing_resolution=mapping.get("timing_resolution"),
                  reader=dict(mapping.get("reader", {})),
                  accuracy=mapping.get("accuracy", "auto"),
                  noise=mapping.get("noise", "auto"), friction=mapping.get("friction"),
                  uncertainty=_uncertainty_methods(mapping.get("uncertainty")), **kwargs)
    _check_drag(scene, source)
    if scene.incline_angle is not None and scene.g_eff is None and \
            scene.driving_acceleration < MIN_DRIVING_ACCELERATION:
        # The schema bounds g_eff itself; a nearly flat incline can undercut it.
        raise InputError(source, f"invalid scene (apparatus/incline_angle: g·sin θ = "
                                 f"{scene.driving_acceleration:.3g} m/s² is less than the "
                                 f"minimum of {MIN_DRIVING_ACCELERATION:g} m/s²)")
    return scene


def _check_drag(scene, source):
    """One InputError line naming the key where the drag keys cannot be used."""
    if not scene.needs_drag:
        for key in _DRAG_KEYS:
            if getattr(scene, key) is not None:
                missing = " and ".join(f"apparatus.{name}" for name in ("mass", "diameter")
                                       if getattr(scene, name) is None)
                raise InputError(source, f"invalid scene (apparatus/{key}: air drag is "
                                         f"modelled only for a ball of known mass and diameter; "
                                         f"{missing} missing)")
        return
    air = (scene.air_density or DEFAULT_AIR_DENSITY).value
    density = scene.mass.value / (math.pi / 6.0 * scene.diameter.value ** 3)
    if density <= air:
        raise InputError(source, f"invalid scene (apparatus/diameter: a ball of "
                                 f"{scene.mass.value:g} kg and {scene.diameter.value:g} m is "
                                 f"no denser ({density:.3g} kg/m³) than the air ({air:g} "
                                 f"kg/m³): it would not fall back)")


def load_scene(path):
    """Read and check a ``scene.yaml``.

    Parameters
    ----------
    path : str or os.PathLike

    Returns
    -------
    Scene
        With ``recording`` resolved against the file's folder and ``name`` defaulting to it.

    Raises
    ------
    InputError
        Missing or unreadable file, not UTF-8, YAML syntax error, a duplicate key, nesting or
        aliases past the bounds of :func:`dashpot.safe_yaml.load_yaml`, or a scene that breaks
        the schema.
    """
    path = Path(path)
    mapping = load_yaml(path, what="scene file")
    if mapping is None:
        mapping = {}
    if not isinstance(mapping, dict):
        raise InputError(path, "a scene file must be a mapping of keys to values")
    scene = scene_from_mapping(mapping, source=path, base=path.parent)
    if "name" not in mapping:
        # The folder's name, which need not follow the pattern a written name must.
        scene = replace(scene, name=path.resolve().parent.name or "scene")
    return scene


def _uncertainty_methods(value):
    """The scene key ``uncertainty`` (one method or a list, schema-checked) as the tuple of
    methods fitted, "covariance" always first."""
    if value is None:
        return ("covariance",)
    methods = [value] if isinstance(value, str) else list(value)
    return tuple(dict.fromkeys(["covariance", *methods]))
