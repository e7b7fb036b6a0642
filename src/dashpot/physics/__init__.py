"""Physics of a linear spring-dashpot contact: single impacts, capture, bounce sequences."""

from .models import MODELS, Collision, collide, critical_velocity

__all__ = ["MODELS", "Collision", "collide", "critical_velocity"]
from .sequence import BounceSequence, bounce_sequence  # noqa: E402
from .units import (  # noqa: E402
    contact_coefficients,
    contact_from_restitution,
    dimensionless_parameters,
    natural_parameters,
    restitution_from_contact,
)

__all__ += ["BounceSequence", "bounce_sequence", "contact_coefficients",
            "contact_from_restitution", "dimensionless_parameters", "natural_parameters",
            "restitution_from_contact"]
from .flight import (  # noqa: E402
    Flight,
    drag_constant,
    drag_flight,
    effective_gravity,
    gravity_flight,
    incline_flight,
    track_flight,
)

__all__ += ["Flight", "drag_constant", "drag_flight", "effective_gravity", "gravity_flight",
            "incline_flight", "track_flight"]
from .laws import (  # noqa: E402
    LADDER,
    LAWS,
    LawParameter,
    Restitution,
    RestitutionLaw,
    dashpot_contact_time,
    hunt_crossley_restitution,
    restitution,
)

__all__ += ["LADDER", "LAWS", "LawParameter", "Restitution", "RestitutionLaw",
            "dashpot_contact_time", "hunt_crossley_restitution", "restitution"]
