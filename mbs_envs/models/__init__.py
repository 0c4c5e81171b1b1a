"""The physics: one file per mechanism, plus the shared base."""

from .base import Model, Params
from .planar2r import Planar2R, Planar2RParams

__all__ = ["Model", "Params", "Planar2R", "Planar2RParams"]
