"""Smooth policies for off-policy agents: CAPS regularization of the actor (Mysore et al., "Regularizing action policies
for smooth control with reinforcement learning", ICRA 2021).

A policy trained on a reward alone may be any function of the state that earns it; near a switching surface it can be
steep, and in closed loop a steep feedback law chatters: the torque jumps between neighbouring states every step, which
a smoothness criterion (the DFKI score's standard deviation of the torque's steps) and a real motor punish. CAPS adds two
terms to the actor's loss, on the deterministic action ``mu(s)`` (in the normalized action box ``[-1, 1]``):

.. math::

    L = L_\\text{actor} + \\lambda_T \\, \\overline{|\\mu(s) - \\mu(s')|^2}
        + \\lambda_S \\, \\overline{|\\mu(s) - \\mu(\\tilde s)|^2},
    \\qquad \\tilde s = s + \\sigma \\varepsilon, \\; \\varepsilon \\sim N(0, I),

the temporal term over stored transitions ``(s, s')`` (consecutive decisions), the spatial term over observations
perturbed by ``sigma`` (in the observation's own units), both averaged over a batch drawn from the replay buffer. The
reward, the observation and the critic are untouched: the regularized actor is an ordinary SB3 policy, saved and loaded
as any other.

The terms are added where SB3 steps the actor's optimizer (after its ``actor_loss.backward()``, before its ``step()``):
:func:`regularize` wraps that one optimizer's ``step`` of a model, on a batch of its own from the replay buffer.
"""

from __future__ import annotations

import dataclasses
from typing import Any

from .. import validation as check


@dataclasses.dataclass(frozen=True)
class CAPS:
    """The weights of the temporal and spatial terms and the observation noise of the spatial one.

    Attributes
    ----------
    temporal : float
        ``lambda_T >= 0`` (on squared normalized actions).
    spatial : float
        ``lambda_S >= 0``.
    sigma : float
        ``> 0``, the standard deviation of the observation perturbation (observation units).
    """

    temporal: float = 1.0
    spatial: float = 1.0
    sigma: float = 0.05

    def __post_init__(self) -> None:
        check.nonnegative(self.temporal, "temporal")
        check.nonnegative(self.spatial, "spatial")
        check.positive(self.sigma, "sigma")

    @classmethod
    def of(cls, spec: Any) -> "CAPS":
        """From an instance, a mapping of the fields or ``"temporal,spatial,sigma"`` (a ``ValueError`` names what is
        wrong)."""
        if isinstance(spec, cls):
            return spec
        if isinstance(spec, str):
            return cls.parse(spec)
        spec = check.mapping(spec, "smooth")
        fields = {f.name for f in dataclasses.fields(cls)}
        if set(spec) - fields:
            raise ValueError(f"smooth: unknown fields {sorted(set(spec) - fields)}; known {sorted(fields)}")
        return cls(**spec)

    @classmethod
    def parse(cls, text: str) -> "CAPS":
        """From ``"temporal,spatial,sigma"`` (the command line's form), or a ``ValueError`` naming it."""
        parts = str(text).split(",")
        try:
            values = [float(x) for x in parts]
        except ValueError:
            values = []
        if len(values) != 3:
            raise ValueError(f"smooth: expected 'temporal,spatial,sigma' (three numbers), got {text!r}")
        return cls(*values)


def mean_action(actor: Any, obs: Any) -> Any:
    """The actor's deterministic action for a batch of observations (SAC: ``tanh`` of the mean; TD3: the output)."""
    try:
        return actor(obs, deterministic=True)
    except TypeError:  # TD3's actor takes no ``deterministic``
        return actor(obs)


def caps_loss(actor: Any, obs: Any, next_obs: Any, noise: Any, caps: CAPS) -> Any:
    """The two CAPS terms (module docstring) for the batch ``obs`` -> ``next_obs``, ``noise`` the standard normal
    draws of the spatial term (shape of ``obs``); a scalar torch tensor."""
    mu = mean_action(actor, obs)
    loss = caps.temporal * ((mu - mean_action(actor, next_obs)) ** 2).sum(-1).mean()
    return loss + caps.spatial * ((mu - mean_action(actor, obs + caps.sigma * noise)) ** 2).sum(-1).mean()


def regularize(model: Any, caps: CAPS) -> None:
    """Make ``model``'s (an SB3 SAC or TD3) actor updates carry the CAPS terms (module docstring).

    Raises
    ------
    ValueError
        ``model`` has no actor optimizer or replay buffer (an on-policy algorithm).
    """
    import torch

    actor = getattr(model, "actor", None)
    if actor is None or getattr(actor, "optimizer", None) is None or not hasattr(model, "replay_buffer"):
        raise ValueError(f"smooth: CAPS needs an off-policy agent with an actor (SAC, TD3), got {type(model).__name__}")
    optimizer = actor.optimizer
    step = optimizer.step

    def regularized_step(closure: Any = None) -> Any:
        data = model.replay_buffer.sample(model.batch_size, env=model._vec_normalize_env)
        obs, next_obs = data.observations, data.next_observations
        caps_loss(actor, obs, next_obs, torch.randn_like(obs), caps).backward()  # added to the actor loss's gradient
        return step(closure)

    optimizer.step = regularized_step
