"""Model-based controllers behind stable-baselines3's ``predict`` protocol.

Each controller is built from an environment, reads the equations from
``env.unwrapped.model`` (never a copy) and acts from the observation alone, so
``stable_baselines3.common.evaluation.evaluate_policy`` scores it exactly as it
scores an RL agent.
"""

from .base import Controller
from .disk import LQR, NoControl, SteeringPD
from .joint import PD, ComputedTorque, PDGravity
from .adaptive_swingup import AdaptiveSwingUpLQR
from .planned_swingup import PlannedSwingUp
from .scored_swingup import ScoredSwingUp
from .mpc_swingup import MPCSwingUp, MPCSettings
from .swingup import SwingUpLQR
from .energy_swingup import EnergySwingUpLQR
from .estimator import RatesFromAngles

__all__ = [
    "Controller",
    "PD",
    "PDGravity",
    "ComputedTorque",
    "LQR",
    "SteeringPD",
    "NoControl",
    "SwingUpLQR",
    "AdaptiveSwingUpLQR",
    "PlannedSwingUp",
    "ScoredSwingUp",
    "MPCSwingUp",
    "MPCSettings",
    "EnergySwingUpLQR",
    "RatesFromAngles",
]
