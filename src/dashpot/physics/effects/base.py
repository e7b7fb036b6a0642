"""What a flight effect is: its parameters, how it enters the flight map, and its rung.

A flight effect (air drag, rolling friction, ...) is a :class:`FlightEffect`: a name, the
acceleration it adds in one line, its parameters (:class:`EffectParameter`: unit, meaning,
default bounds and start), how it changes the coefficients of the flight law (:class:`Track`,
the closed form :func:`dashpot.physics.flight.track_flight`), the quantities a fit derives from
its parameters (:class:`DerivedQuantity`), and where it stands in a fit: how a scene sets its
columns up (start values, bounds, a prior or a fixed value from scene keys, why a value is
held, :class:`EffectSetup`), whether the dashpot models' fits try it as a nested step, the rung
it makes on the noise fits' selection ladder and the note the verdict carries where its rung
was tried. Nothing here knows any particular effect: they are defined in
the modules beside this one and collected in :data:`dashpot.physics.effects.FLIGHT_EFFECTS`.

This module imports nothing of the package but the flight law, so that every effect module can
import it.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

__all__ = ["Column", "DerivedQuantity", "EffectParameter", "EffectSetup", "FlightEffect",
           "Track"]


@dataclass(frozen=True)
class Track:
    """Coefficients of the flight law :func:`dashpot.physics.flight.track_flight`.

    The body decelerates at ``gravity + away`` (m/s²) moving away from the surface and
    accelerates at ``gravity − toward`` (m/s²) on its way back, with the quadratic drag
    ``drag``·v|v| (k_d in 1/m) both ways. Floats or arrays (one value per parameter set).

    Attributes
    ----------
    gravity : float or ndarray
        Acceleration towards the surface without the effects' own, in m/s² (g, or a fitted
        g_eff).
    away : float or ndarray
        Extra deceleration while moving away, in m/s².
    toward : float or ndarray
        Deceleration subtracted from `gravity` on the way back, in m/s².
    drag : float or ndarray
        Quadratic drag constant k_d in 1/m.
    """

    gravity: object
    away: object = 0.0
    toward: object = 0.0
    drag: object = 0.0

    @property
    def up(self):
        """a_up = gravity + away, in m/s²."""
        return self.gravity + self.away

    @property
    def down(self):
        """a_down = gravity − toward, in m/s²."""
        return self.gravity - self.toward


@dataclass(frozen=True)
class EffectParameter:
    """One parameter of a flight effect.

    Attributes
    ----------
    name : str
        Name as fitted (a column of the noise fit, a key of its estimates).
    unit : str
        SI unit.
    description : str
        What it is, in plain words (reports; a joint fit's estimate adds ", shared").
    lower, upper, start : float
        Default fit bounds and start value, where the effect's ``setup`` takes them (an effect
        whose bounds scale with the scene, as friction's with g_eff, sets its own). A start
        off zero: the fast level's optimizer differences each column with a step relative to
        its value.
    detail : str
        How it enters, in a few symbols (``"deceleration k_d v^2"``), shown after the
        description in a single fit's estimate ("" for none).
    step : float or None
        The noise fit optimizer's first step in this parameter, about its standard error, in
        its unit; None: 1e-3 of g (an acceleration).
    """

    name: str
    unit: str
    description: str
    lower: float = 0.0
    upper: float = math.inf
    start: float = 0.0
    detail: str = ""
    step: float | None = None

    @property
    def meaning(self):
        """The description with its detail: the note of a fitted estimate."""
        return f"{self.description} ({self.detail})" if self.detail else self.description


@dataclass(frozen=True)
class DerivedQuantity:
    """A quantity a fit reports from an effect's parameters (a_away = g_eff + f, ...), with its
    error by linear propagation.

    Attributes
    ----------
    name : str
        Key of the fit's estimates.
    unit : str
        SI unit.
    description : str
        Its formula or meaning (the estimate's note).
    value : callable
        ``value(columns) -> float`` from the fitted columns by name.
    gradient : callable
        ``gradient(columns) -> dict`` of ∂q/∂p by parameter name (parameters left out add
        nothing).
    """

    name: str
    unit: str
    description: str
    value: Callable
    gradient: Callable


@dataclass(frozen=True)
class Column:
    """One parameter of an effect as set up for one fit.

    Attributes
    ----------
    name : str
        The parameter's name.
    start : float
        Start value (and the value held where `fixed`).
    lower, upper : float
        Fit bounds.
    prior : float or None
        Standard deviation of a Gaussian prior centred on `start` (None: no prior).
    fixed : bool
        Held at `start` (a value the scene states exactly).
    reason : str
        Why it is held, where `fixed` (the note of a dashpot model's estimate; "" for the
        parameter's meaning).
    """

    name: str
    start: float
    lower: float
    upper: float
    prior: float | None = None
    fixed: bool = False
    reason: str = ""


@dataclass(frozen=True)
class EffectSetup:
    """An effect's columns in one fit (in the order of its parameters) and the fit's note.

    Attributes
    ----------
    columns : tuple of Column
    note : str
        The note of a fit carrying the effect.
    model_note : str or None
        The note of a dashpot model's fit (:func:`dashpot.fit.fit_model`) where it words it
        otherwise ("" for none, where the scene's notes say it already); None: `note`.
    """

    columns: tuple[Column, ...]
    note: str
    model_note: str | None = None

    @property
    def dashpot_note(self):
        """The note of a dashpot model's fit ("" for none)."""
        return self.note if self.model_note is None else self.model_note


@dataclass(frozen=True)
class FlightEffect:
    """A flight effect: its parameters, how it enters the flight law and its ladder rung.

    Attributes
    ----------
    name : str
        Registry key, the name a fit asks for (``effects=(name,)``) and the effect the
        selection names.
    formula : str
        The acceleration it adds, in one line.
    parameters : tuple of EffectParameter
        In the order ``enter`` takes them (the order of the fit's columns).
    enter : callable
        ``enter(track, *params) -> Track``: the flight law's coefficients with the effect in,
        on arrays (one value per parameter set) or floats.
    reference : str
        Where its physics comes from.
    setup : callable, optional
        ``setup(scene, g, requested) -> EffectSetup or None``: the effect's columns in a fit
        of `scene` (a :class:`dashpot.scene.Scene`; g in m/s²), `requested` whether the fit
        asks for the effect; None where the fit leaves it out. Default: the parameters free
        at their default bounds and start where requested or in every fit (`in_scene`),
        else out.
    in_scene : callable, optional
        ``in_scene(scene) -> bool``: the scene puts the effect in every fit (drag where it
        gives the ball's mass and diameter); then ``setup`` is asked with `requested` false
        too, and there is no rung. Default: never.
    tried : callable, optional
        ``tried(scene) -> bool``: whether a scene's ladder fits the effect's rung (where it is
        not in every fit already). Default: always.
    extends : str
        The restitution law whose rung the effect extends (``"constant"``): the rung is that
        law with the effect, named ``extends + "+" + name``.
    caveat : str
        Note of the selection verdict where the rung was tried: what the data cannot tell
        about the effect ("" for none).
    carried : callable, optional
        ``carried(fit, name) -> str or None``: a note of the verdict on the selected fit
        `fit` (named `name`) where the effect is in it without a rung (the scene's).
    meaning : str
        The effect in plain words (``"rolling friction"``), in the fits' notes; default its
        name.
    derived : tuple of DerivedQuantity
        What a fit carrying the effect reports beside its parameters.
    stepped : callable, optional
        ``stepped(scene) -> bool``: whether the dashpot models' fits of `scene`
        (:func:`dashpot.fit.fit_model`) try the effect as a nested step: the model fitted
        again with it, kept where it lowers the BIC enough. Default: never (a fit still
        carries it where the scene puts it in every fit or the fit asks for it).
    speed_start : callable, optional
        ``speed_start(launch, landing, duration, columns) -> dict or None``: start values of
        the effect's parameters from a motion sensor's measured flights (launch and landing
        speeds in m/s, durations in s; flights of this effect alone, no other), with
        ``columns`` its parameters' (start, lower, upper) by name; None where the flights do
        not give them. Default: none (the setup's start values).
    """

    name: str
    formula: str
    parameters: tuple[EffectParameter, ...]
    enter: Callable
    reference: str
    setup: Callable | None = None
    in_scene: Callable | None = None
    tried: Callable | None = None
    extends: str = "constant"
    caveat: str = ""
    carried: Callable | None = None
    meaning: str = ""
    derived: tuple[DerivedQuantity, ...] = ()
    stepped: Callable | None = None
    speed_start: Callable | None = None

    @property
    def label(self):
        """The effect in plain words: its meaning, else its name."""
        return self.meaning or self.name

    @property
    def parameter_names(self):
        """Names of the parameters, in call order."""
        return tuple(p.name for p in self.parameters)

    @property
    def rung(self):
        """Name of the effect's rung on the selection ladder: ``"constant+drag"``, ..."""
        return f"{self.extends}+{self.name}"

    def columns(self, scene, g, requested):
        """The effect's :class:`EffectSetup` in a fit of `scene`, or None where it is out.

        The effect's own ``setup`` where it has one; else its parameters free at their
        default bounds and start, where `requested` or where the scene puts it in every fit.
        """
        if self.setup is not None:
            return self.setup(scene, g, requested)
        if not requested and not self.in_every_fit(scene):
            return None
        columns = tuple(Column(p.name, p.start, p.lower, p.upper) for p in self.parameters)
        return EffectSetup(columns, f"{self.name}: {self.formula}, "
                                    f"{', '.join(self.parameter_names)} fitted free")

    def in_every_fit(self, scene):
        """Whether `scene` puts the effect in every fit (see :attr:`in_scene`)."""
        return bool(self.in_scene is not None and self.in_scene(scene))

    def has_rung(self, scene):
        """Whether `scene`'s ladder fits the effect's rung."""
        return not self.in_every_fit(scene) and (self.tried is None or bool(self.tried(scene)))

    def steps_in(self, scene):
        """Whether the dashpot models' fits of `scene` try the effect as a nested step (see
        :attr:`stepped`; never where the scene puts it in every fit)."""
        return (not self.in_every_fit(scene) and self.stepped is not None
                and bool(self.stepped(scene)))
