"""Gymnasium tasks on the models: spaces, reset distribution, reward, termination, render.

Scenes on constrained models (four-bar, rolling disk) load on first use (see
:mod:`mbs_envs.models`).
"""

from ..lazy import lazy_exports
from .base import MBSEnv
from .planar2r import Planar2REnv
from .serial_chain import SerialChainEnv
from .tracking import JointTrackingEnv, TrackingObservation, decode_tracking, encode_tracking

_LAZY = {
    "FourBarEnv": "fourbar",
    "RollingDiskEnv": "rolling_disk",
    "DiskObservation": "rolling_disk",
    "SpatialChainEnv": "spatial_chain",
}

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


__getattr__, __dir__ = lazy_exports(__name__, _LAZY, globals())
