"""dashpot: bouncing-ball recordings to linear spring-dashpot contact physics."""

from importlib.metadata import PackageNotFoundError, version

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

try:
    __version__ = version("dashpot")
except PackageNotFoundError:  # running from a source tree without installation
    __version__ = "0+unknown"

__all__ = ["MODELS", "BounceSequence", "Collision", "bounce_sequence", "collide",
           "contact_coefficients", "contact_from_restitution", "critical_velocity",
           "dimensionless_parameters", "natural_parameters", "restitution_from_contact",
           "parameter_table", "report_text", "__version__"]
