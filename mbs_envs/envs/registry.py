"""The scene registry: every scene declared once, read by the package and the scripts.

A scene is a model file (``mbs_envs/models/<scene>.py``), a task file
(``mbs_envs/envs/<scene>.py``) and one :class:`Scene` entry in :data:`SCENES`.
From it, ``import mbs_envs`` registers the Gymnasium id (with the batched
``vector_entry_point``), and the comparison, tuning, training and benchmark
code find the scene's controllers, residual base and whether actuator sizing
applies; the reliability suite its model and edge parameters; the numerics
studies its free motions and its stiff and singular cases (functions in the
task file). Entries are plain data (entry points as ``"module:attr"`` strings), so
reading the registry imports no scene: constrained scenes load the constraint
machinery only when made.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from types import MappingProxyType

#: the tracking task's model-based controllers (fully actuated scenes)
JOINT_CONTROLLERS = MappingProxyType(
    {
        "PD": "mbs_envs.controllers:PD",
        "PD+gravity": "mbs_envs.controllers:PDGravity",
        "computed torque": "mbs_envs.controllers:ComputedTorque",
    }
)

#: the swing-up scenes' model-based controller (underactuated: no joint tracking controller applies)
SWING_UP_CONTROLLERS = MappingProxyType(
    {
        "swing-up + LQR": "mbs_envs.controllers:SwingUpLQR",
        "adaptive swing-up + LQR": "mbs_envs.controllers:AdaptiveSwingUpLQR",
        "identified iLQR + TVLQR": "mbs_envs.controllers:PlannedSwingUp",
    }
)
#: controllers designed for the DFKI protocol ids alone (their design is the protocol plant's; not run on our own
#: swing-up scenes)
PROTOCOL_CONTROLLERS = MappingProxyType(
    {
        "score-designed swing-up + TVLQR": "mbs_envs.controllers:ScoredSwingUp",
        "iLQR MPC + LQR": "mbs_envs.controllers:MPCSwingUp",
    }
)


@dataclasses.dataclass(frozen=True)
class Scene:
    """One scene.

    Attributes
    ----------
    name : str
        Short name (report tables, ``--scene`` options).
    id : str
        Gymnasium id.
    entry_point : str
        ``"module:Class"`` of the single env (its vector env is the batched engine over it).
    max_episode_steps : int
        Truncation of the registered id.
    controllers : Mapping[str, str]
        Model-based controllers by display name -> ``"module:Class"``.
    residual_base : str
        The base controller of a residual RL agent when none is named.
    sizing : bool
        Whether actuator sizing along the reference applies (a joint-space reference).
    kwargs : Mapping
        ``gym.make`` keywords of the configuration compared and benchmarked.
    model : str
        ``"module:Class"`` of the model (the reliability suite builds it with edge parameters).
    edge_parameters : tuple of (str, Mapping)
        Parameters the reliability suite drives to their edges (0, negative, NaN, inf,
        tiny, huge), each with the other parameters it needs (e.g. ``r1 = 0`` for ``I1``).
    scoring : {"tracking", "swing-up"}
        How the comparison scores an episode (:data:`mbs_envs.studies.evaluation.SCORING`):
        tracking error after the first second, or success, time to swing up and energy.
    bench_kwargs : tuple of Mapping
        The configurations ``scripts/bench_scenes.py`` times (default: ``kwargs`` alone).
    free_motions : str
        ``"module:function"`` returning the scene's free motions for the work-precision study,
        a sequence of ``(label, model, q0, v0, stabilization)``
        (:func:`mbs_envs.studies.work_precision.free_problems`); "" for none.
    stiff_cases : str
        ``"module:function"`` of ``quick: bool`` returning the scene's stiff and extreme cases,
        a list of :class:`mbs_envs.studies.numerics.Case` (:func:`mbs_envs.studies.stiff_cases.stiff_cases`).
    singular_cases : str
        ``"module:function"`` returning cases whose true motion ends at a coordinate singularity
        (:func:`mbs_envs.studies.stiff_cases.singular_cases`).
    compared : bool
        Whether the comparison, the tuning and the benchmarks run it (False for an earlier
        version of a task kept registered, e.g. ``Acrobot-v0`` beside ``Acrobot-v1``).
    """

    name: str
    id: str
    entry_point: str
    max_episode_steps: int
    controllers: Mapping[str, str] = dataclasses.field(default_factory=lambda: JOINT_CONTROLLERS)
    residual_base: str = "mbs_envs.controllers:ComputedTorque"
    sizing: bool = True
    kwargs: Mapping = dataclasses.field(default_factory=dict)
    model: str = ""
    edge_parameters: tuple = ()
    scoring: str = "tracking"
    bench_kwargs: tuple = ()
    free_motions: str = ""
    stiff_cases: str = ""
    singular_cases: str = ""
    compared: bool = True


SCENES: tuple[Scene, ...] = (
    Scene("Planar2R", "mbs_envs/Planar2R-v0", "mbs_envs.envs.planar2r:Planar2REnv", 500,
          model="mbs_envs.models.planar2r:Planar2R", edge_parameters=(("m2", {}), ("l1", {}), ("I1", {"r1": 0.0})),
          free_motions="mbs_envs.studies.scene_cases:planar2r_free_motions", stiff_cases="mbs_envs.studies.scene_cases:planar2r_stiff_cases"),
    Scene("FourBar", "mbs_envs/FourBar-v0", "mbs_envs.envs.fourbar:FourBarEnv", 500,
          model="mbs_envs.models.fourbar:FourBar", edge_parameters=(("m2", {}), ("l2", {})),
          free_motions="mbs_envs.studies.scene_cases:fourbar_free_motions", stiff_cases="mbs_envs.studies.scene_cases:fourbar_stiff_cases"),
    Scene("SerialChain", "mbs_envs/SerialChain-v0", "mbs_envs.envs.serial_chain:SerialChainEnv", 500,
          model="mbs_envs.models.serial_chain:SerialChain", edge_parameters=(("m", {"n_links": 5}), ("l", {"n_links": 5})),
          bench_kwargs=({"n_links": 10}, {"n_links": 100}),
          free_motions="mbs_envs.studies.scene_cases:serial_chain_free_motions", stiff_cases="mbs_envs.studies.scene_cases:serial_chain_stiff_cases"),
    Scene("SpatialChain", "mbs_envs/SpatialChain-v0", "mbs_envs.envs.spatial_chain:SpatialChainEnv", 500,
          model="mbs_envs.models.spatial_chain:SpatialChain", edge_parameters=(("m", {"n_links": 5}), ("l", {"n_links": 5})),
          bench_kwargs=({"n_links": 10}, {"n_links": 100}),
          free_motions="mbs_envs.studies.scene_cases:spatial_chain_free_motions", stiff_cases="mbs_envs.studies.scene_cases:spatial_chain_stiff_cases"),
    Scene(
        "RollingDisk", "mbs_envs/RollingDisk-v0", "mbs_envs.envs.rolling_disk:RollingDiskEnv", 1000,
        controllers=MappingProxyType({"LQR": "mbs_envs.controllers:LQR", "PD steering": "mbs_envs.controllers:SteeringPD", "no control": "mbs_envs.controllers:NoControl"}),
        residual_base="mbs_envs.controllers:LQR", sizing=False,
        model="mbs_envs.models.rolling_disk:RollingDisk", edge_parameters=(("m", {}), ("r", {})),
        free_motions="mbs_envs.studies.scene_cases:rolling_disk_free_motions", stiff_cases="mbs_envs.studies.scene_cases:rolling_disk_stiff_cases",
        singular_cases="mbs_envs.studies.scene_cases:rolling_disk_singular_cases",
    ),
    Scene("SliderCrank", "mbs_envs/SliderCrank-v0", "mbs_envs.envs.slider_crank:SliderCrankEnv", 500,
          model="mbs_envs.envs.slider_crank:SliderCrank", edge_parameters=(("m2", {}), ("l", {})),
          free_motions="mbs_envs.studies.scene_cases:slider_crank_free_motions"),
    Scene("CartDoublePendulum", "mbs_envs/CartDoublePendulum-v0", "mbs_envs.envs.cart_double_pendulum:CartDoublePendulumEnv", 500,
          model="mbs_envs.envs.cart_double_pendulum:CartDoublePendulum", edge_parameters=(("m2", {}), ("l1", {})),
          free_motions="mbs_envs.studies.scene_cases:cart_double_pendulum_free_motions"),
    Scene("CartPoleSwingUp", "mbs_envs/CartPoleSwingUp-v0", "mbs_envs.envs.cart_pole:CartPoleSwingUpEnv", 1000,
          controllers=MappingProxyType({"energy swing-up + LQR": "mbs_envs.controllers:EnergySwingUpLQR"}),
          residual_base="mbs_envs.controllers:EnergySwingUpLQR", sizing=False, scoring="swing-up",
          model="mbs_envs.envs.cart_pole:CartPole", edge_parameters=(("m", {}), ("l", {})),
          free_motions="mbs_envs.studies.scene_cases:cart_pole_free_motions"),
    *(
        Scene(
            name + suffix, f"mbs_envs/{name}-{version}", f"mbs_envs.envs.{module}:{name}{cls}Env", 1500,
            controllers=SWING_UP_CONTROLLERS, residual_base="mbs_envs.controllers:SwingUpLQR", sizing=False, scoring="swing-up",
            model="mbs_envs.models.planar2r:Planar2R", edge_parameters=(("m2", {}), ("l1", {})), compared=compared,
        )
        # v1 (the hold bonus) is the compared task; v0 stays registered under its own name; v2 (the LQR region's
        # reward) is the task the pure RL agents train on (mbs_envs.envs.swingup_v2)
        for version, suffix, module, cls, compared in (("v1", "", "swingup", "V1", True), ("v0", "-v0", "swingup", "", False),
                                                       ("v2", "-v2", "swingup_v2", "V2", False))
        for name in ("Acrobot", "Pendubot")
    ),
)  # fmt: skip


def load(target: str):
    """The object named by a ``"module:attr"`` entry (imports the module)."""
    import importlib

    module, _, attr = target.partition(":")
    return getattr(importlib.import_module(module), attr)


def scene(key: str) -> Scene:
    """The scene with this name or Gymnasium id; for a protocol id (:data:`mbs_envs.envs.presets.PROTOCOL_IDS` and
    ``TRAINING_IDS``) the scene of its task class with the protocol's id, episode length and preset (not compared:
    the protocol studies run it).

    Raises
    ------
    ValueError
        Naming the known scenes.
    """
    for s in SCENES:
        if key in (s.name, s.id):
            return s
    from .presets import PROTOCOL_IDS, TRAINING_IDS

    for pid, entry, preset, steps in PROTOCOL_IDS + TRAINING_IDS:
        if key == pid:
            base = next(s for s in SCENES if s.entry_point == entry)
            return dataclasses.replace(base, name=pid.split("/")[-1], id=pid, max_episode_steps=steps,
                                       kwargs=MappingProxyType({"preset": preset}), compared=False)  # fmt: skip
    raise ValueError(f"unknown scene {key!r}; known: {[s.name for s in SCENES]} or {[s.id for s in SCENES]}")
