"""Training under the robustness axes: a vector env whose members meet, episode by episode, one perturbation.

A robustness sweep (:mod:`mbs_envs.studies.robustness`) perturbs the closed loop along one axis at a time:
measurement noise, torque noise, a lagging actuator, an observation delay, torque pulses (and the plant's
parameters, which the vector env's ``randomize=`` draws already). :class:`PerturbedVectorEnv` trains under the same
perturbations, with the same arithmetic (:func:`~mbs_envs.envs.perturbations.actuated`,
:func:`~mbs_envs.envs.perturbations.delayed`, :func:`~mbs_envs.envs.perturbations.with_noise`): at each reset a
member draws one axis of :class:`TrainingPerturbations` (or none) uniformly, and a value uniform over the axis'
range, and keeps them for the episode. The reward is the env's, of the true state; the agent sees the perturbed
observation.

    from mbs_envs.envs.perturbed import PerturbedVectorEnv, TrainingPerturbations
    from mbs_envs.envs.sb3 import make_sb3_vec_env

    venv = make_sb3_vec_env("mbs_envs/Acrobot-v1", n_envs=16, seed=0, action_repeat=10, preset="dfki_c1",
                            max_episode_steps=5000, perturb=TrainingPerturbations.dfki())   # 10 s: the pulses fit

The wrapped env runs with ``autoreset_mode="Disabled"`` (a member's episode ends, then the caller resets it with
``options={"reset_mask": ...}``, as :class:`~mbs_envs.envs.sb3.SB3VecEnv` does), so that every perturbation
setting belongs to exactly one episode.
"""

from __future__ import annotations

import dataclasses
from types import MappingProxyType
from typing import Any, Mapping

import numpy as np
from gymnasium.vector import AutoresetMode, VectorWrapper

from .. import validation as check
from .actions import validate_action

#: the axes a member can draw at a reset, in this order ("nominal": none)
TRAINING_AXES = ("nominal", "velocity noise", "torque noise", "torque response", "time delay", "perturbations")
#: each axis' field of :class:`TrainingPerturbations`
AXIS_FIELDS = MappingProxyType(
    {
        "velocity noise": "velocity_noise",
        "torque noise": "torque_noise",
        "torque response": "torque_response",
        "time delay": "time_delay",
        "perturbations": "pulses",
    }
)


def _range(value: Any, name: str, low: float, high: float) -> tuple[float, float] | None:
    if value is None:
        return None
    try:
        a, b = (float(x) for x in value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a range (low, high) or None, got {value!r}") from None
    a = check.real(a, f"{name}[0]", low, high)
    b = check.real(b, f"{name}[1]", low, high)
    if a > b:
        raise ValueError(f"{name} must have low <= high, got {value!r}")
    return (a, b)


@dataclasses.dataclass(frozen=True)
class TrainingPerturbations:
    """The ranges a member's perturbation is drawn from at each reset (None: the axis is never drawn).

    Attributes
    ----------
    velocity_noise : (float, float), optional
        Std of the Gaussian noise on the observation entries ``noise_index`` (drawn afresh each step).
    noise_index : tuple of int
        The observation entries the measurement noise reaches (e.g. the joint rates).
    torque_noise : (float, float), optional
        Std of the Gaussian noise added to each commanded torque [N m] (drawn afresh each step).
    torque_response : (float, float), optional
        Responsiveness ``r`` of a first-order actuator ``u_k = u_{k-1} + r (u_cmd - u_{k-1})`` (1: ideal).
    time_delay : (float, float), optional
        Observation delay [s], rounded to whole control steps.
    pulses : mapping, optional
        Random torque pulses on every joint (:func:`mbs_envs.envs.perturbations.random_pulses`): ``per_joint``,
        ``min_spacing`` [s], ``sigma`` (width range [s]), ``amplitude`` (height range [N m]).
    """

    velocity_noise: tuple[float, float] | None = None
    noise_index: tuple[int, ...] = ()
    torque_noise: tuple[float, float] | None = None
    torque_response: tuple[float, float] | None = None
    time_delay: tuple[float, float] | None = None
    pulses: Mapping[str, Any] | None = None

    def __post_init__(self) -> None:
        big = 1e6
        set_ = lambda k, v: object.__setattr__(self, k, v)  # noqa: E731
        set_("velocity_noise", _range(self.velocity_noise, "velocity_noise", 0.0, big))
        set_("torque_noise", _range(self.torque_noise, "torque_noise", 0.0, big))
        set_("torque_response", _range(self.torque_response, "torque_response", 1e-6, 2.0))
        set_("time_delay", _range(self.time_delay, "time_delay", 0.0, 10.0))
        try:
            index = tuple(check.integer(i, "noise_index", 0, 10**6) for i in self.noise_index)
        except TypeError:
            raise ValueError(f"noise_index must be observation indices, got {self.noise_index!r}") from None
        set_("noise_index", index)
        if self.pulses is not None:
            p = check.mapping(self.pulses, "pulses")
            missing = {"per_joint", "min_spacing", "sigma", "amplitude"} - set(p)
            if missing or set(p) - {"per_joint", "min_spacing", "sigma", "amplitude", "episodes"}:
                raise ValueError(f"pulses needs exactly per_joint, min_spacing, sigma, amplitude, got {sorted(p)}")
            set_("pulses", {"per_joint": check.integer(p["per_joint"], "pulses['per_joint']", 1, 1000),
                            "min_spacing": check.real(p["min_spacing"], "pulses['min_spacing']", 0.0, big),
                            "sigma": _range(p["sigma"], "pulses['sigma']", 1e-9, big),
                            "amplitude": _range(p["amplitude"], "pulses['amplitude']", 0.0, big)})  # fmt: skip

    @property
    def axes(self) -> tuple[str, ...]:
        """The axes a member draws from (:data:`TRAINING_AXES` that are set; "nominal" always)."""
        return ("nominal",) + tuple(a for a in TRAINING_AXES[1:] if getattr(self, AXIS_FIELDS[a]) is not None)

    @classmethod
    def dfki(cls) -> TrainingPerturbations:
        """The DFKI benchmark's robustness-v2 ranges (:mod:`mbs_envs.envs.perturbations`), rates observed at 4 and 5."""
        from .perturbations import PULSES, RANGES, RATE_INDEX

        r = RANGES
        pulses = {k: PULSES[k] for k in ("per_joint", "min_spacing", "sigma", "amplitude")}
        return cls(velocity_noise=r["velocity noise"], noise_index=RATE_INDEX, torque_noise=r["torque noise"],
                   torque_response=r["torque response"], time_delay=r["time delay"], pulses=pulses)  # fmt: skip

    @classmethod
    def of(cls, spec: Any) -> TrainingPerturbations:
        """From ``"dfki"``, a mapping of the fields, or an instance (a ``ValueError`` names what is wrong)."""
        if isinstance(spec, cls):
            return spec
        if spec == "dfki":
            return cls.dfki()
        fields = {f.name for f in dataclasses.fields(cls)}
        spec = check.mapping(spec, "perturb")
        if set(spec) - fields:
            raise ValueError(f"perturb: unknown fields {sorted(set(spec) - fields)}; known {sorted(fields)}")
        return cls(**spec)

    def as_dict(self) -> dict[str, Any]:
        """The fields as JSON-ready values (what :meth:`of` reads back)."""
        return {f.name: (list(v) if isinstance(v, tuple) else dict(v) if isinstance(v, Mapping) else v)
                for f in dataclasses.fields(self) for v in [getattr(self, f.name)]}  # fmt: skip


class PerturbedVectorEnv(VectorWrapper):
    """A batched mbs_envs vector env (``autoreset_mode="Disabled"``) whose members each meet one perturbation per
    episode (the module docstring).

    Parameters
    ----------
    env : MBSVectorEnv
        With ``autoreset_mode="Disabled"`` and a ``max_episode_steps``.
    perturbations : TrainingPerturbations or "dfki" or mapping
    seed : int, optional
        Seeds the wrapper's own generator (axes, values, noise, pulses); None: fresh entropy.

    Attributes
    ----------
    axis : ndarray of int (num_envs,)
        Each member's axis this episode, an index into :attr:`TrainingPerturbations.axes`.
    """

    def set_attr(self, name: str, values: Any) -> None:
        """The wrapped env's :meth:`~mbs_envs.envs.vector.MBSVectorEnv.set_attr` (Gymnasium's rule)."""
        self.env.set_attr(name, values)

    def get_attr(self, name: str) -> tuple:
        """The wrapped env's ``get_attr``."""
        return self.env.get_attr(name)

    def __init__(self, env: Any, perturbations: Any, seed: int | None = None):
        from .vector import MBSVectorEnv

        if not isinstance(getattr(env, "unwrapped", None), MBSVectorEnv):
            raise ValueError(f"env must be an mbs_envs vector env, got {type(env).__name__}")
        if env.autoreset_mode != AutoresetMode.DISABLED:
            raise ValueError(
                f"env needs autoreset_mode=Disabled (one perturbation per episode), got {env.autoreset_mode.name}"
            )
        if env.unwrapped.max_episode_steps is None:
            raise ValueError("env needs a max_episode_steps (the pulses are drawn for a whole episode)")
        perturbations = TrainingPerturbations.of(perturbations)
        seed = check.seed(seed)
        base = env.unwrapped
        width = env.single_observation_space.shape[0]
        if any(i >= width for i in perturbations.noise_index):
            raise ValueError(
                f"perturbations.noise_index {perturbations.noise_index} beyond the observation's {width} entries"
            )
        n, nv, dt, steps = base.num_envs, base.model.nv, float(base.env.dt), int(base.max_episode_steps)
        if perturbations.pulses is not None:
            q = perturbations.pulses
            if steps * dt < (nv * q["per_joint"] + 1) * q["min_spacing"]:
                raise ValueError(f"perturbations.pulses: {nv * q['per_joint']} pulses {q['min_spacing']} s apart do not fit "
                                 f"in an episode of {steps * dt:g} s")  # fmt: skip
        super().__init__(env)
        self.perturbations = perturbations
        self.rng = np.random.default_rng(None if seed is None else [seed, 0x9E47])  # not a member's stream (seed + i)
        nu = base.model.nu
        self.dt, self.steps = dt, steps
        self.u_max = np.asarray(base.env.u_max, float)
        delay_max = 0 if perturbations.time_delay is None else int(np.rint(perturbations.time_delay[1] / self.dt))
        self.history = np.zeros((delay_max + 1, n, width), env.single_observation_space.dtype)
        self.k = np.zeros(n, int)
        self.axis = np.zeros(n, int)
        self.value = np.zeros(n)
        self.delay = np.zeros(n, int)
        self.applied = np.zeros((n, nu))
        self.pulses = np.zeros((n, self.steps if perturbations.pulses else 0, nv))

    @property
    def autoreset_mode(self) -> AutoresetMode:
        """The wrapped env's (Disabled)."""
        return self.env.autoreset_mode

    def _draw(self, idx: np.ndarray, obs: np.ndarray) -> None:
        """Members ``idx`` begin an episode with the observation ``obs`` (theirs, rows of the batch)."""
        p, axes = self.perturbations, self.perturbations.axes
        axis = self.rng.integers(len(axes), size=len(idx))
        scalar = [a not in ("nominal", "perturbations") for a in axes]  # the axes with a value drawn from a range
        value = np.array([self.rng.uniform(*getattr(p, AXIS_FIELDS[axes[a]])) if scalar[a] else 0.0 for a in axis])
        self.axis[idx], self.value[idx] = axis, value
        self.delay[idx] = np.where([axes[a] == "time delay" for a in axis], np.rint(value / self.dt), 0).astype(int)
        self.k[idx] = 0
        self.applied[idx] = 0.0
        self.history[0, idx] = obs[idx]
        if p.pulses is not None:
            hit = idx[[axes[a] == "perturbations" for a in axis]]
            self.pulses[idx] = 0.0
            if len(hit):
                from .perturbations import random_pulses

                q = p.pulses
                self.pulses[hit] = random_pulses(self.rng, len(hit), np.arange(self.steps) * self.dt, self.pulses.shape[2],
                                                 q["per_joint"], q["min_spacing"], q["sigma"], q["amplitude"])  # fmt: skip

    def _seen(self, obs: np.ndarray) -> np.ndarray:
        """The observations the members see at their step :attr:`k` (``obs``: the true ones, already in the ring)."""
        from .perturbations import delayed, with_noise

        seen = delayed(self.history, self.k, self.delay) if self.delay.any() else obs
        sigma = np.where(self._on("velocity noise"), self.value, 0.0)
        if sigma.any():
            idx = list(self.perturbations.noise_index) or slice(None)
            seen = with_noise(seen, idx, sigma[:, None] * self.rng.standard_normal(seen[:, idx].shape))
        return seen

    def _on(self, name: str) -> np.ndarray:
        axes = self.perturbations.axes
        return self.axis == axes.index(name) if name in axes else np.zeros(len(self.axis), bool)

    def reset(self, *, seed: Any = None, options: dict | None = None):
        options = dict(check.mapping(options, "options"))
        mask = options.get("reset_mask")
        obs, info = self.env.reset(seed=seed, options=options)  # refuses bad input before anything here changes
        idx = np.arange(self.num_envs) if mask is None else np.flatnonzero(mask)
        self._draw(idx, obs)
        return self._seen(obs), info

    def step(self, actions: Any):
        from .perturbations import actuated

        base = self.env.unwrapped
        u = (
            validate_action(actions, len(self.u_max), self.num_envs) * self.u_max
        )  # saturated to [-1, 1]; refused as the env does
        sigma = np.where(self._on("torque noise"), self.value, 0.0)
        noise = sigma[:, None] * self.rng.standard_normal(u.shape) if sigma.any() else None
        lag = self._on("torque response")
        response = np.where(lag, self.value, 1.0) if lag.any() else None
        applied = actuated(u, self.applied, self.u_max, noise, response)
        if self._on("perturbations").any():  # the others' rows are zeros: no solve for a batch without pulses
            base.apply_impulse(self.pulses[np.arange(self.num_envs), np.minimum(self.k, self.steps - 1)] * self.dt)
        obs, reward, terminated, truncated, info = self.env.step((applied / self.u_max).astype(np.float32))
        self.applied = applied
        self.k += 1
        self.history[self.k % len(self.history), np.arange(self.num_envs)] = obs
        return self._seen(obs), reward, terminated, truncated, info
