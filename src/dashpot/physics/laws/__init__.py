"""A ladder of restitution laws ε(v), beside the five dashpot models, as rebound maps.

Each law gives the coefficient of restitution ε at the impact speed v and its speed slope, and
a ``rebound`` adapter turns it into the rebound speed R(v) = ε(v)·v with dR/dv, the form
:class:`dashpot.likelihood.TrainModel` takes. The registry :data:`LAWS` lists every law with its
parameters' names, units, fit bounds and start values.

==================  ===========================================  ======================  =====
law                 ε(v)                                         parameters              ref.
==================  ===========================================  ======================  =====
constant            e                                            e                       —
linear              e0 − α·v                                     e0, α (s/m)             —
quadratic           e0 − c·v²                                    e0, c (s²/m²)           —
power               a·v^(−b)  (v in m/s)                         a, b                    —
viscoelastic-hertz  1 − C1·δ + C2·δ² + δ·q(δ),  δ = κ·v^(1/5)   κ (s^(1/5)/m^(1/5))     [1]_
hunt-crossley       root of ln((1 + d)/(1 − dε)) = d(1 + ε),     χ = λ/k (s/m)           [2]_
                    d = χ·v
Ia … hybrid         dashpot model at ṽ = v/v*                     ζ, v* = g/ω0 (m/s)      [3]_
==================  ===========================================  ======================  =====

Layout: one module per law or family of laws, each defining its laws as
:class:`RestitutionLaw` specs in a tuple ``LAW_SPECS``; :data:`LAWS` is built from the modules
listed in ``_MODULES`` (:mod:`.base` holds the types and knows no law):

=========================  ===============================================================
module                     laws
=========================  ===============================================================
``constant``               constant (the base of the ladder)
``speed_terms``            linear, quadratic, power
``viscoelastic_hertz``     viscoelastic-hertz (the Chebyshev table of its remainder)
``hunt_crossley``          hunt-crossley (its compiled kernels in ``physics/law_kernels.py``)
``dashpot_models``         Ia, Ib, IIa, IIb, hybrid (with their contact durations)
=========================  ===============================================================

A new law is one new module here that defines ``LAW_SPECS = (RestitutionLaw(...),)`` (its name,
formula, parameters with units, bounds and start values, the vectorized
``function(speed, *params) -> (eps, v·dε/dv, outside)``, a reference and, where the default
start values will not do, a ``start(eps, typical_speed)`` hook), plus its module's name in
``_MODULES``. The fits under the noise model (:func:`dashpot.fit.fit_noise_model`) then fit it,
:data:`LADDER` (and so the noise fits of every scene) includes it after the laws before it, and
the noise selection compares it with its ``simpler`` rung (the constant law by default) as the
``effect`` it adds ("speed term" by default). :func:`register` adds a law at run time.

Domain. A law never returns ε outside [0, 1] silently: where its formula leaves [0, 1] (a
constant above 1, a linear law past v = e0/α, a power law below the speed where a·v^(−b) = 1)
ε is clipped to the bound, its slope set to 0 and the point flagged in
:attr:`Restitution.outside`; the same flag marks the viscoelastic law beyond its table. A fit
should keep the flagged points out (or note them): clipping is what keeps the train
simulations NaN-free, not a physical statement.

The formulas, their derivations and the numerics are in each law's module.

References
----------
.. [1] R. Ramírez, T. Pöschel, N. V. Brilliantov and T. Schwager, "Coefficient of restitution
   of colliding viscoelastic spheres", Phys. Rev. E 60, 4465-4472 (1999).
.. [2] K. H. Hunt and F. R. E. Crossley, "Coefficient of restitution interpreted as damping in
   vibroimpact", J. Appl. Mech. 42, 440-445 (1975).
.. [3] S. P. Bartz, "Coefficient of restitution of a linear dashpot on a rigid surface",
   sections 3-4 (models Ia, Ib, IIa, IIb, hybrid).
"""

from __future__ import annotations

from . import constant as _constant
from . import dashpot_models as _dashpot_models
from . import hunt_crossley as _hunt_crossley
from . import speed_terms as _speed_terms
from . import viscoelastic_hertz as _viscoelastic_hertz
from ..._registry import unregister as _unregister
from .base import Derived, LawParameter, Restitution, RestitutionLaw
from .dashpot_models import dashpot_contact_time, dashpot_step
from .hunt_crossley import hunt_crossley_restitution
from .viscoelastic_hertz import (
    VISCOELASTIC_C1,
    VISCOELASTIC_C2,
    VISCOELASTIC_DELTA_MAX,
    viscoelastic_contact_restitution,
)

__all__ = ["LADDER", "LAWS", "Derived", "LawParameter", "Restitution", "RestitutionLaw",
           "VISCOELASTIC_C1", "VISCOELASTIC_C2", "VISCOELASTIC_DELTA_MAX",
           "dashpot_contact_time", "dashpot_step", "hunt_crossley_restitution", "register",
           "restitution", "unregister", "viscoelastic_contact_restitution"]

_MODULES = (_constant, _speed_terms, _viscoelastic_hertz, _hunt_crossley, _dashpot_models)
"""The modules whose ``LAW_SPECS`` make the registry, in its order: the ladder's rungs
simplest first, then the dashpot models."""


def _check(law, known):
    """ValueError where `law` cannot join a registry holding the names `known`."""
    if not isinstance(law, RestitutionLaw):
        raise ValueError(f"a restitution law must be a RestitutionLaw; got {law!r}")
    if law.name in known:
        raise ValueError(f"restitution law {law.name!r} is already registered")
    if not law.parameters or not callable(law.function):
        raise ValueError(f"restitution law {law.name!r} needs parameters and a function")
    for p in law.parameters:
        if not p.lower <= p.start <= p.upper:
            raise ValueError(f"restitution law {law.name!r}: start of {p.name} outside its "
                             f"bounds [{p.lower}, {p.upper}]")
    if law.simpler is not None and law.simpler not in known:
        raise ValueError(f"restitution law {law.name!r}: its simpler rung {law.simpler!r} "
                         f"is not registered before it")
    return law


def _registry(modules):
    laws = {}
    for module in modules:
        for law in module.LAW_SPECS:
            laws[law.name] = _check(law, laws)
    return laws


LAWS = _registry(_MODULES)
"""Every restitution law by name: the ladder's rungs, then the five dashpot models."""

LADDER = tuple(name for name, law in LAWS.items() if law.contact is None)
"""Names of the ladder's rungs (the laws without a contact duration), simplest first: the laws
every noise fit of a scene tries (the dashpot models follow in :data:`LAWS`)."""


def register(law):
    """Add `law` to :data:`LAWS` at run time (a law of its own module joins at import).

    Parameters
    ----------
    law : RestitutionLaw
        A name not yet registered, start values inside the bounds, its ``simpler`` rung
        registered.

    Returns
    -------
    RestitutionLaw
        `law`, now ``LAWS[law.name]`` (not added to :data:`LADDER`, a tuple fixed at import:
        fit it by name).

    Raises
    ------
    ValueError
        A name already taken or an incomplete law.
    """
    LAWS[law.name] = _check(law, LAWS)
    return law


def unregister(name):
    """Remove a law added by :func:`register`; the laws of the modules stay.

    Raises
    ------
    ValueError
        `name` is not registered, or is one of the modules' laws.
    """
    _unregister(LAWS, name, {law.name for module in _MODULES for law in module.LAW_SPECS},
                "restitution law")


def restitution(name, speed, *params):
    """ε of the law `name` at `speed` (m/s): ``LAWS[name](speed, *params)``.

    Raises
    ------
    ValueError
        Unknown law (the message lists the known ones) or bad arguments.
    """
    if name not in LAWS:
        raise ValueError(f"restitution law must be one of {', '.join(map(repr, LAWS))}; "
                         f"got {name!r}")
    return LAWS[name](speed, *params)
