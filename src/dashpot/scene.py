"""A scene: one recording plus what is known of the apparatus that made it.

Known quantities are fixed in the fits (or enter as priors when given with an uncertainty);
unknown ones are fitted; effects a scene does not declare are not modelled. A scene is read from
a ``scene.yaml`` (documented in ``config/README.md``) or built from a mapping; both are checked
against the JSON schema shipped with the package, and a bad file gives one
:class:`~dashpot.errors.InputError` line naming it.

References
----------
.. [1] S. P. Bartz, "Coefficient of restitution of a linear dashpot on a rigid surface":
   the cart on an incline, g_eff = g·sin θ along the track.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields, replace
from importlib.resources import files
from pathlib import Path

from .errors import InputError
from .physics.models import MODELS
from .safe_yaml import load_yaml

__all__ = ["Known", "Scene", "load_scene", "scene_from_mapping", "STANDARD_GRAVITY"]

STANDARD_GRAVITY = 9.80665  # m/s², conventional value (CGPM 1901)
MIN_DRIVING_ACCELERATION = 1e-3  # m/s², as the schema's g_eff: a track level to 1e-4 rad


@dataclass(frozen=True)
class Known:
    """A quantity the scene knows: its value and, for a prior, its 1σ uncertainty (same unit).

    ``uncertainty`` None means the value is taken as exact and the parameter is fixed.
    """

    value: float
    uncertainty: float | None = None


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
        Options for the reader (flag_length, gate_distance, bumper_position, unit).
    accuracy : str
        Numerical accuracy level of the fits ("auto", "fast", "standard", "exact").
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

    @property
    def driving_acceleration(self):
        """Acceleration back towards the surface in m/s²: g_eff, else g·sin θ, else g [1]_."""
        if self.g_eff is not None:
            return self.g_eff
        if self.incline_angle is not None:
            return self.gravity * math.sin(math.radians(self.incline_angle))
        return self.gravity

    @property
    def known_impact_speed(self):
        """Known first impact speed (m/s) from the scene, or None: √(2 g_eff h) for a drop."""
        if self.first_impact_speed is not None:
            return self.first_impact_speed
        if self.drop_height is not None:
            g = self.driving_acceleration
            speed = math.sqrt(2.0 * g * self.drop_height.value)
            spread = self.drop_height.uncertainty
            # dv/dh = g/v: the height's uncertainty carried to the speed.
            return Known(speed, None if spread is None else g * spread / speed)
        return None

    def as_dict(self):
        """Plain mapping of the scene (for provenance records)."""
        out = {}
        for item in fields(self):
            value = getattr(self, item.name)
            if isinstance(value, Known):
                value = {"value": value.value, "uncertainty": value.uncertainty}
            elif isinstance(value, Path):
                value = str(value)
            elif isinstance(value, tuple):
                value = list(value)
            out[item.name] = value
        out["driving_acceleration"] = self.driving_acceleration
        return out


_KNOWN_KEYS = ("mass", "stiffness", "first_impact_speed", "drop_height")


def _schema():
    import yaml

    return yaml.safe_load(files("dashpot").joinpath("scene.schema.yaml").read_text())


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
    import jsonschema

    mapping = dict(mapping or {})
    try:
        jsonschema.validate(mapping, _schema())
    except jsonschema.ValidationError as error:
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
    recording = mapping.get("recording")
    if recording is not None:
        recording = Path(base or ".") / recording
    models = tuple(mapping.get("models", MODELS))
    scene = Scene(name=str(mapping.get("name", Path(str(source)).parent.name or "scene")),
                  sensor=mapping.get("sensor"), recording=recording, models=models,
                  timing_resolution=mapping.get("timing_resolution"),
                  reader=dict(mapping.get("reader", {})),
                  accuracy=mapping.get("accuracy", "auto"), **kwargs)
    if scene.incline_angle is not None and scene.g_eff is None and \
            scene.driving_acceleration < MIN_DRIVING_ACCELERATION:
        # The schema bounds g_eff itself; a nearly flat incline can undercut it.
        raise InputError(source, f"invalid scene (apparatus/incline_angle: g·sin θ = "
                                 f"{scene.driving_acceleration:.3g} m/s² is less than the "
                                 f"minimum of {MIN_DRIVING_ACCELERATION:g} m/s²)")
    return scene


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
