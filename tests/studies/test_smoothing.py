"""CAPS regularization of an off-policy actor (:mod:`mbs_envs.studies.smoothing`)."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from mbs_envs.studies.smoothing import CAPS, caps_loss, mean_action, regularize
from mbs_envs.studies.training import ALGOS, TrainConfig, train


def test_settings_are_checked_and_parsed():
    assert (
        CAPS.parse("1,2.5,0.1")
        == CAPS(1.0, 2.5, 0.1)
        == CAPS.of("1,2.5,0.1")
        == CAPS.of({"temporal": 1, "spatial": 2.5, "sigma": 0.1})
    )
    caps = CAPS()
    assert CAPS.of(caps) is caps
    with pytest.raises(ValueError, match="unknown fields.*lambda"):
        CAPS.of({"temporal": 1, "lambda": 2})
    with pytest.raises(ValueError, match="smooth"):
        CAPS.of(3.0)
    for bad in ("1,2", "a,b,c", "1,2,3,4"):
        with pytest.raises(ValueError, match="smooth"):
            CAPS.parse(bad)
    for kw, name in ((dict(temporal=-1), "temporal"), (dict(spatial=np.nan), "spatial"), (dict(sigma=0.0), "sigma")):
        with pytest.raises(ValueError, match=name):
            CAPS(**kw)
    with pytest.raises(ValueError, match="ppo"):
        TrainConfig("mbs_envs/Pendubot-v2", "ppo", 100, smooth="1,1,0.05")
    assert TrainConfig("mbs_envs/Pendubot-v2", "sac", 100, smooth="1,1,0.05").smooth == {
        "temporal": 1.0,
        "spatial": 1.0,
        "sigma": 0.05,
    }


def test_the_loss_is_the_two_mean_squared_differences_written_out():
    torch.manual_seed(0)
    actor = torch.nn.Sequential(torch.nn.Linear(3, 5), torch.nn.Tanh(), torch.nn.Linear(5, 2), torch.nn.Tanh())
    obs, nxt, noise = torch.randn(7, 3), torch.randn(7, 3), torch.randn(7, 3)
    caps = CAPS(0.3, 2.0, 0.1)
    mu, mu2, mu3 = actor(obs), actor(nxt), actor(obs + 0.1 * noise)
    by_hand = 0.3 * np.mean(np.sum((mu - mu2).detach().numpy() ** 2, 1)) + 2.0 * np.mean(
        np.sum((mu - mu3).detach().numpy() ** 2, 1)
    )
    assert float(caps_loss(actor, obs, nxt, noise, caps)) == pytest.approx(by_hand, rel=1e-6)  # float32 sums
    assert float(caps_loss(actor, obs, obs, torch.zeros_like(obs), caps)) == 0.0  # a constant-in-time, noiseless batch


@pytest.mark.parametrize("algo", ["sac", "td3"])
def test_the_actor_step_adds_exactly_the_caps_gradient(algo):
    """At the actor optimizer's step of a regularized model, the CAPS loss's gradient on the batch and noise the step
    drew is added to what SB3's actor loss left (here nothing: the step is called on zeroed gradients); recomputed from
    the same random state. The step itself runs with a zero learning rate so the weights stay put for the recomputation."""
    model = ALGOS[algo]("MlpPolicy", "Pendulum-v1", learning_starts=0, batch_size=16, policy_kwargs={"net_arch": [8, 8]},
                        device="cpu", seed=0)  # fmt: skip
    model.learn(64)  # a filled buffer
    caps = CAPS(0.7, 1.3, 0.05)
    regularize(model, caps)
    actor, params = model.actor, list(model.actor.parameters())
    for g in actor.optimizer.param_groups:
        g["lr"] = 0.0
    state = torch.get_rng_state(), np.random.get_state()
    actor.optimizer.zero_grad()
    actor.optimizer.step()
    got = [None if p.grad is None else p.grad.clone() for p in params]  # SAC's log-std head: not on the mean's path
    torch.set_rng_state(state[0])
    np.random.set_state(state[1])
    data = model.replay_buffer.sample(model.batch_size, env=model._vec_normalize_env)
    actor.optimizer.zero_grad()
    caps_loss(actor, data.observations, data.next_observations, torch.randn_like(data.observations), caps).backward()
    assert all((a is None and p.grad is None) or torch.equal(a, p.grad) for a, p in zip(got, params))
    assert any(a is not None and float(a.abs().max()) > 0 for a in got)
    assert mean_action(actor, data.observations).shape == (16, 1)


def test_regularize_refuses_an_on_policy_agent():
    model = ALGOS["ppo"]("MlpPolicy", "Pendulum-v1", n_steps=16, device="cpu")
    with pytest.raises(ValueError, match="off-policy"):
        regularize(model, CAPS())


def test_a_smoothed_run_records_its_setting_and_ships_an_ordinary_agent(tmp_path):
    config = TrainConfig("mbs_envs/Pendubot-v2", "sac", 400, n_envs=2, action_repeat=4, eval_seeds=1, net_arch=(8, 8),
                         hyper={"learning_starts": 10}, smooth="1,1,0.05")  # fmt: skip
    record = train(config, tmp_path)
    assert record["smooth"] == {"temporal": 1.0, "spatial": 1.0, "sigma": 0.05}
    assert json.loads((tmp_path / "config.json").read_text())["smooth"] == record["smooth"]
    ALGOS["sac"].load(tmp_path / "agent.zip", device="cpu")
