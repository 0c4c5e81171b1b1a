"""Gymnasium tasks on the models: spaces, reset distribution, reward, termination, render."""

from .base import MBSEnv
from .fourbar import FourBarEnv
from .planar2r import Planar2REnv
from .rolling_disk import DiskObservation, RollingDiskEnv
from .serial_chain import SerialChainEnv
from .tracking import JointTrackingEnv, TrackingObservation, decode_tracking, encode_tracking

__all__ = [
    "MBSEnv",
    "FourBarEnv",
    "JointTrackingEnv",
    "Planar2REnv",
    "RollingDiskEnv",
    "SerialChainEnv",
    "DiskObservation",
    "TrackingObservation",
    "decode_tracking",
    "encode_tracking",
]
