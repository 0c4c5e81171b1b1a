"""PlannedSwingUp's settings: grouped in frozen dataclasses, validated in one place, the flat names routed to them."""

from __future__ import annotations

import dataclasses

import gymnasium as gym
import numpy as np
import pytest

import mbs_envs  # noqa: F401
from mbs_envs.controllers.planned_settings import HoldSettings, PlanSettings, split_settings
from mbs_envs.controllers.planned_swingup import PlannedSwingUp


def test_the_flat_names_and_the_settings_objects_build_the_same_controller():
    env = gym.make("mbs_envs/Acrobot-v1")
    flat = PlannedSwingUp(env, hold=False, plan_time=1.5, w_u=0.2, hold_law="edge", edge=0.07)
    grouped = PlannedSwingUp(
        env, plan=PlanSettings(plan_time=1.5, w_u=0.2), hold=HoldSettings(enabled=False, hold_law="edge", edge=0.07)
    )
    assert flat.plan_settings == grouped.plan_settings and flat.hold_settings == grouped.hold_settings
    for name in ("plan_steps", "w_u", "max_steps", "tail", "edge", "hold_law", "hold"):
        assert getattr(flat, name) == getattr(grouped, name), name
    np.testing.assert_array_equal(flat.Q_edge, grouped.Q_edge)
    with pytest.raises(dataclasses.FrozenInstanceError):
        flat.plan_settings.w_u = 1.0


@pytest.mark.parametrize(
    "kwargs, culprit",
    [({"w_u": -1.0}, "w_u"), ({"margin": 1.5}, "margin"), ({"iterations": 2.5}, "iterations"), ({"plan_h": 0.0}, "plan_h"),
     ({"hold_q": (1.0, 2.0)}, "hold_q"), ({"hold_law": "magic"}, "hold_law"), ({"hold_back": 0.5}, "hold_back"),
     ({"hold_noise": (1e-5, -1.0)}, "hold_noise"), ({"hold_trigger": 0.5}, "hold_trigger"), ({"plan_tme": 1.0}, "plan_tme"),
     ({"hold_omega": 1e4}, "hold_omega"), ({"hold_rescue_reach": 0.5}, "hold_rescue_reach")],
)  # fmt: skip
def test_a_bad_setting_is_refused_by_name_before_anything_is_built(kwargs, culprit):
    env = gym.make("mbs_envs/Acrobot-v1")
    with pytest.raises(ValueError, match=culprit):
        PlannedSwingUp(env, hold=False, **kwargs)


def test_split_settings_routes_each_name_to_the_one_that_has_it():
    plan, hold = split_settings(None, True, {"catch_tol": 0.02, "hold_r": 2e-3})
    assert plan == PlanSettings(catch_tol=0.02) and hold == HoldSettings(enabled=True, hold_r=2e-3)
    with pytest.raises(ValueError, match="plan must be a PlanSettings"):
        split_settings({"w_u": 1.0}, None, {})
