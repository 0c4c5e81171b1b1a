"""Serial scenes do not load the constraint machinery (checked in a fresh interpreter)."""

from __future__ import annotations

import subprocess
import sys

CODE = """
import sys
import gymnasium as gym
import numpy as np
import mbs_envs
for env_id in ("mbs_envs/Planar2R-v0", "mbs_envs/SerialChain-v0", "mbs_envs/Acrobot-v0", "mbs_envs/Pendubot-v0"):
    env = gym.make(env_id)
    env.reset(seed=0)
    for _ in range(3):
        env.step(env.action_space.sample())
    envs = gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point")
    envs.reset(seed=0)
    envs.step(envs.action_space.sample())
mbs_envs.simulate(mbs_envs.models.Planar2R(), [0.1, 0.2], [0.0, 0.0], 0.05)
loaded = sorted(m for m in sys.modules if m in ("mbs_envs.dynamics.constraints", "mbs_envs.models.constrained",
                                              "mbs_envs.models.fourbar", "mbs_envs.models.rolling_disk"))
print(",".join(loaded))
from mbs_envs.models import FourBar  # the constrained scenes still load on first use
print("mbs_envs.dynamics.constraints" in sys.modules)
"""


def test_serial_scenes_do_not_import_the_constraint_machinery():
    out = subprocess.run([sys.executable, "-c", CODE], capture_output=True, text=True, check=True).stdout.split("\n")
    assert out[0] == "", f"loaded by serial scenes: {out[0]}"
    assert out[1] == "True"


def test_the_registry_is_the_one_list_of_scenes():
    import gymnasium as gym
    import pytest

    import mbs_envs
    from mbs_envs.studies import comparison
    from mbs_envs.envs import registry
    from mbs_envs.studies.training import residual_base

    ids = [s.id for s in registry.SCENES]
    assert len(set(ids)) == len(ids) and len({s.name for s in registry.SCENES}) == len(ids)
    assert set(mbs_envs.ENV_IDS) == set(ids)
    for s in registry.SCENES:
        spec = gym.spec(s.id)
        assert spec.entry_point == s.entry_point and spec.max_episode_steps == s.max_episode_steps
        assert registry.scene(s.name) is registry.scene(s.id) is s
        if s.compared:
            assert comparison.SCENES[s.name] == (s.id, dict(s.kwargs), dict(s.controllers))
        else:  # an earlier task version, kept registered, not compared
            assert s.name not in comparison.SCENES
        assert residual_base(s.id) == s.residual_base
    with pytest.raises(ValueError, match="unknown scene 'Pendulum'"):
        registry.scene("Pendulum")


def test_every_scene_names_its_model_edge_parameters_and_a_consistent_moving_state():
    """What the reliability suite reads from the registry (no per-scene table elsewhere)."""
    import gymnasium as gym
    import numpy as np

    from mbs_envs.envs import registry

    for s in registry.SCENES:
        cls = registry.load(s.model)
        assert type(gym.make(s.id).unwrapped.model) is cls
        assert s.edge_parameters and all(name in cls.Params.names() for name, _ in s.edge_parameters)
        model = cls(**dict(s.edge_parameters[0][1]))
        q, v = model.moving_state()
        assert q.shape == (model.nq,) and v.shape == (model.nv,) and np.any(v != 0)
        if model.nc:
            assert np.max(model.constraint_violation(q, v)) < 1e-9  # consistency_tol of the envs


def test_no_module_aliases_and_nothing_generic_at_the_top_level():
    """Modules are imported by their own paths; the controllers live under the package's namespace."""
    import importlib.util
    import pickle

    import mbs_envs
    from mbs_envs.studies.residual import ResidualPolicy

    assert not hasattr(mbs_envs, "MOVED")
    assert importlib.util.find_spec("mbs_envs.sb3") is None  # old flat paths are gone, not served
    assert pickle.loads(pickle.dumps(ResidualPolicy)) is ResidualPolicy
    assert callable(mbs_envs.simulate)  # the name stays the function after its module was imported
    import mbs_envs.controllers

    assert mbs_envs.controllers.PD.__module__ == "mbs_envs.controllers.joint"
    top = sorted(p.stem for p in mbs_envs.dynamics.jit.PACKAGE.glob("*.py"))
    assert top == ["__init__", "lazy", "simulate", "validation"], top


def test_the_numerics_studies_take_their_cases_from_the_registry(monkeypatch):
    """Free motions, stiff and singular cases are declared by each scene's registry entry (functions in
    its task file): the studies list exactly those, and a new entry's cases join them."""
    import dataclasses

    import numpy as np

    from mbs_envs.envs import registry
    from mbs_envs.studies import numerics, stiff_cases, work_precision

    free = work_precision.free_problems(0.2)
    stiff, singular = stiff_cases.stiff_cases(quick=True), stiff_cases.singular_cases()
    declared = [s for s in registry.SCENES if s.free_motions]
    assert {s.name for s in declared} == {
        "Planar2R",
        "FourBar",
        "SerialChain",
        "SpatialChain",
        "RollingDisk",
        "SliderCrank",
        "CartDoublePendulum",
        "CartPoleSwingUp",
    }
    assert [p.name for p in free] == [f"{m[0]}-free" for s in declared for m in registry.load(s.free_motions)()]
    assert all(p.steps == 5 and p.q0.dtype == np.float64 for p in free)
    for p in free:  # every free motion starts consistent with its model's constraints
        assert np.max(p.model.constraint_violation(p.q0, p.v0)) < 1e-9, p.name
    names = [c.scene for c in stiff + singular]
    assert len(set(names)) == len(names) and all(isinstance(c, numerics.Case) for c in stiff + singular)
    assert [c.scene for c in singular] == ["disk falls flat"]
    assert len(stiff_cases.stiff_cases(quick=False)) == len(stiff) + 2  # the 500-link chains, planar and spatial
    fourbar = registry.scene("FourBar")
    extra = dataclasses.replace(fourbar, name="FourBar2", id="mbs_envs/FourBar2-v0")
    monkeypatch.setattr(registry, "SCENES", registry.SCENES + (extra,))
    assert len(stiff_cases.stiff_cases(quick=True)) == len(stiff) + len(registry.load(fourbar.stiff_cases)())
    assert len(work_precision.free_problems(0.2)) == len(free) + 1


def test_the_controllers_kernels_are_stamped_with_the_package_sources():
    """A kernel of mbs_envs.controllers is cached under the package's stamp, as every kernel of the package: a cache
    written under another module path or by other sources is never loaded (numba's own rule keys a file's cache by
    its modification time alone, and a cache written when the folder was the top-level ``controllers`` named a
    module that no longer exists)."""
    from mbs_envs.controllers import trajectory
    from mbs_envs.dynamics import jit

    assert any(str(root).endswith("controllers") for root in jit.source_roots())
    locator = trajectory.step4._cache._impl.locator
    assert type(locator).__name__.startswith("MbsEnvs") and locator.get_source_stamp() == jit.package_stamp()
