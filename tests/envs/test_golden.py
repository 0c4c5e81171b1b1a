"""Observations, rewards and episodes equal those recorded from an earlier version (tests/golden.py).

Rewards and energies are float64: equal to 1e-12 (relative to max(1, |x|)).
Observations are float32: a float64 value that moved by 1e-12 may round to the
neighbouring float32, so they are compared to one float32 spacing.
Terminations must be identical.
"""

from __future__ import annotations

import numpy as np
import pytest

from tests import golden

RECORDED = np.load(golden.PATH)


@pytest.mark.parametrize("kind", ["single", "vector"])
@pytest.mark.parametrize("case", golden.CASES, ids=[c[0] for c in golden.CASES])
def test_episodes_equal_the_recorded_version(case, kind):
    label, env_id, kwargs, seed = case
    run = golden.single_episode if kind == "single" else golden.vector_episode
    now = run(env_id, kwargs, seed)
    for key in ("reward", "energy"):
        old = RECORDED[f"{label}/{kind}/{key}"]
        new = now[key]
        if kind == "vector" and key == "energy":
            # on the step that resets a member (next-step autoreset, after its episode ended) the recorded
            # version reported the discarded step's energy; it is now the reset state's, as SyncVectorEnv
            # gives it (issue 34, class 5; tests/envs/test_reliability3.py checks those rows)
            ended = RECORDED[f"{label}/{kind}/terminated"]
            reset_rows = np.concatenate([np.zeros_like(ended[:1]), ended[:-1]])
            old, new = np.where(reset_rows, 0.0, old), np.where(reset_rows, 0.0, new)
        np.testing.assert_allclose(new, old, rtol=0, atol=1e-12 * max(1.0, float(np.max(np.abs(old)))), err_msg=key)
    np.testing.assert_array_equal(now["terminated"], RECORDED[f"{label}/{kind}/terminated"])
    old = RECORDED[f"{label}/{kind}/obs"]
    assert now["obs"].shape == old.shape and now["obs"].dtype == old.dtype == np.float32
    np.testing.assert_array_less(np.abs(now["obs"].astype(float) - old), np.spacing(np.abs(old)) * 1.0001 + 1e-30)
