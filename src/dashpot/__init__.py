"""dashpot: bouncing-ball recordings to linear spring-dashpot contact physics.

The Python API in four functions (:mod:`dashpot.api`)::

    import dashpot
    impacts, scene_fit = dashpot.analyze("drop.wav", "scene.yaml")
    print(scene_fit.report())      # the summary `dashpot analyze` prints
    scene_fit.parameters           # one row per model and parameter (pandas)

and step by step: :func:`load_scene`, :func:`read_impacts`, :func:`fit_scene`. The physics
of one contact and of whole bounce sequences (:func:`collide`, :func:`bounce_sequence`, ...)
is here too, from :mod:`dashpot.physics`.

Every name is imported on first use (PEP 562 module ``__getattr__``), so ``import dashpot``
loads none of numpy, scipy, numba, pandas, lmfit or matplotlib: a command's ``--help`` or
``--version`` starts at once, and a script pays only for what it uses.
"""

from __future__ import annotations

import importlib
import importlib.util
from importlib.metadata import PackageNotFoundError, version
from typing import TYPE_CHECKING

try:
    __version__ = version("dashpot")
except PackageNotFoundError:  # running from a source tree without installation
    __version__ = "0+unknown"

# Public name -> the module (relative to this package) that defines it.
_LAZY = {
    **dict.fromkeys(("analyze", "read_impacts", "load_scene", "fit_scene"), ".api"),
    **dict.fromkeys(("Scene",), ".scene"),
    **dict.fromkeys(("InputError",), ".errors"),
    **dict.fromkeys(("parameter_table", "report_text"), ".fit_report"),
    **dict.fromkeys(("MODELS", "BounceSequence", "Collision", "bounce_sequence", "collide",
                     "contact_coefficients", "contact_from_restitution", "critical_velocity",
                     "dimensionless_parameters", "natural_parameters",
                     "restitution_from_contact"), ".physics"),
}

__all__ = ["analyze", "read_impacts", "load_scene", "fit_scene", "Scene", "InputError",
           "MODELS", "BounceSequence", "Collision", "bounce_sequence", "collide",
           "contact_coefficients", "contact_from_restitution", "critical_velocity",
           "dimensionless_parameters", "natural_parameters", "restitution_from_contact",
           "parameter_table", "report_text", "__version__"]

if TYPE_CHECKING:  # what static checkers and editors see; at run time __getattr__ imports
    from .api import analyze, fit_scene, load_scene, read_impacts
    from .errors import InputError
    from .fit_report import parameter_table, report_text
    from .physics import (
        MODELS,
        BounceSequence,
        Collision,
        bounce_sequence,
        collide,
        contact_coefficients,
        contact_from_restitution,
        critical_velocity,
        dimensionless_parameters,
        natural_parameters,
        restitution_from_contact,
    )
    from .scene import Scene


def __getattr__(name):
    """Import a public name, or a submodule (``dashpot.physics`` after ``import dashpot``),
    on first use, and keep it in the module's namespace."""
    if name in _LAZY:
        value = getattr(importlib.import_module(_LAZY[name], __name__), name)
    elif not name.startswith("_") and importlib.util.find_spec(f"{__name__}.{name}"):
        value = importlib.import_module(f"{__name__}.{name}")
    else:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    globals()[name] = value
    return value


def __dir__():
    return sorted({*globals(), *_LAZY})
