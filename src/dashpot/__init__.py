"""dashpot: bouncing-ball recordings to linear spring-dashpot contact physics."""

from importlib.metadata import PackageNotFoundError, version

from .physics import MODELS, Collision, collide, critical_velocity

try:
    __version__ = version("dashpot")
except PackageNotFoundError:  # running from a source tree without installation
    __version__ = "0+unknown"

__all__ = ["MODELS", "Collision", "collide", "critical_velocity", "__version__"]
