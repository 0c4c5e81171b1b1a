"""The physics: one file per mechanism, plus the shared base."""

from .base import Model, Params
from .fourbar import FourBar, FourBarParams, grashof_class
from .planar2r import Planar2R, Planar2RParams
from .serial_chain import SerialChain, SerialChainParams
from .rolling_disk import RollingDisk, RollingDiskParams, critical_spin

__all__ = [
    "FourBar",
    "FourBarParams",
    "Model",
    "Params",
    "Planar2R",
    "Planar2RParams",
    "RollingDisk",
    "RollingDiskParams",
    "SerialChain",
    "SerialChainParams",
    "critical_spin",
    "grashof_class",
]
