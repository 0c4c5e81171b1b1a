"""The tuning procedure's scoring (mbs_envs/studies/tuning.py)."""

import mbs_envs  # noqa: F401
from mbs_envs.studies.comparison import Condition
from mbs_envs.studies.tuning import score


def test_a_conditions_noise_and_delay_reach_the_scored_rollout():
    """``score`` applies a condition's observation noise and input delay (as the comparison does): the same candidate
    scores differently under each than at the nominal plant, and the nominal score is what it was without them."""
    seeds, kwargs = [20000, 20001], {"max_episode_steps": 150}
    entry = {"omega": 10.0, "zeta": 1.0}
    nominal = score("Planar2R", "PD", entry, seeds, (Condition("nominal"),), **kwargs)
    noisy = score("Planar2R", "PD", entry, seeds, (Condition("nominal"), Condition("noise", obs_noise=0.05)), **kwargs)
    late = score("Planar2R", "PD", entry, seeds, (Condition("late", delay=3),), **kwargs)
    assert noisy.per_condition["nominal"] == nominal.per_condition["nominal"]
    assert noisy.per_condition["noise"] != nominal.per_condition["nominal"]
    assert late.per_condition["late"] != nominal.per_condition["nominal"]
