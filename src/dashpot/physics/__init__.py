"""Physics of a linear spring-dashpot contact: single impacts, capture, bounce sequences."""

from .models import MODELS, Collision, collide, critical_velocity

__all__ = ["MODELS", "Collision", "collide", "critical_velocity"]
