"""The physics: one file per mechanism, plus the shared base.

The constrained mechanisms (four-bar, rolling disk) and the constraint machinery
they need load on first use: ``from mbs_envs.models import FourBar`` works as
usual, while a serial scene never imports :mod:`mbs_envs.constraints`.
"""

import importlib

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
}

__all__ = ["Model", "Params", "Planar2R", "Planar2RParams", "SerialChain", "SerialChainParams", *_LAZY]


def __getattr__(name: str):
    if name in _LAZY:
        value = getattr(importlib.import_module(f".{_LAZY[name]}", __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
