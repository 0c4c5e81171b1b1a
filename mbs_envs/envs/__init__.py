"""Gymnasium tasks on the models: spaces, reset distribution, reward, termination, render.

Scenes on constrained models (four-bar, rolling disk) load on first use (see
:mod:`mbs_envs.models`).
"""

import importlib

from .base import MBSEnv
from .planar2r import Planar2REnv
from .serial_chain import SerialChainEnv
from .tracking import JointTrackingEnv, TrackingObservation, decode_tracking, encode_tracking

_LAZY = {"FourBarEnv": "fourbar", "RollingDiskEnv": "rolling_disk", "DiskObservation": "rolling_disk"}

__all__ = [
    "MBSEnv",
    "JointTrackingEnv",
    "Planar2REnv",
    "SerialChainEnv",
    "TrackingObservation",
    "decode_tracking",
    "encode_tracking",
    *_LAZY,
]


def __getattr__(name: str):
    if name in _LAZY:
        value = getattr(importlib.import_module(f".{_LAZY[name]}", __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
