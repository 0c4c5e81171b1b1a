"""The physics: one file per mechanism, plus the shared base.

The constrained mechanisms (four-bar, rolling disk) and the constraint machinery
they need load on first use: ``from mbs_envs.models import FourBar`` works as
usual, while a serial scene never imports :mod:`mbs_envs.dynamics.constraints`.
"""

from ..lazy import lazy_exports
from .base import Model, Params
from .planar2r import Planar2R, Planar2RParams
from .serial_chain import SerialChain, SerialChainParams

#: names served on first access: name -> submodule
_LAZY = {
    "FourBar": "fourbar",
    "FourBarParams": "fourbar",
    "grashof_class": "fourbar",
    "RollingDisk": "rolling_disk",
    "RollingDiskParams": "rolling_disk",
    "critical_spin": "rolling_disk",
    "SpatialChain": "spatial_chain",
    "SpatialChainParams": "spatial_chain",
}

__all__ = ["Model", "Params", "Planar2R", "Planar2RParams", "SerialChain", "SerialChainParams", *_LAZY]


__getattr__, __dir__ = lazy_exports(__name__, _LAZY, globals())
