"""What ``symbolic.derive`` refuses up front, naming the culprit: keywords as parameter names, terms the generated
code cannot compute smoothly, complex numbers, explicit time dependence."""

import pytest
import sympy as sp

from mbs_envs.models import symbolic
from mbs_envs.models.symbolic import dynamicsymbols

t = symbolic.time_symbol()
q1, q2 = dynamicsymbols("q1 q2")
m, g = sp.symbols("m g")
T = m * (q1.diff(t) ** 2 + q2.diff(t) ** 2) / 2
PARAMS = {"m": (1.0, "positive"), "g": 9.81}


@pytest.mark.parametrize("name", ["lambda", "class", "None", "True", "False", "import"])
def test_a_keyword_is_no_parameter_name(name, tmp_path):
    with pytest.raises(ValueError, match=f"'{name}' is not a usable parameter name"):
        symbolic.derive("Box", [q1, q2], T, g * q1, {**PARAMS, name: 1.0}, cache=tmp_path)


@pytest.mark.parametrize("term, culprit", [
    (sp.Abs(q1), "Abs"), (sp.sign(q1), "sign"), (sp.floor(q1), "floor"), (sp.Heaviside(q1), "Heaviside"),
    (sp.Piecewise((q1, q1 > 0), (0, True)), "Piecewise"), (sp.Max(q1, q2), "Max"), (sp.Min(q1, 0), "Min"),
    (sp.Function("f")(q1), "f"),
])  # fmt: skip
def test_a_potential_the_generated_code_cannot_compute_is_refused_naming_it(term, culprit, tmp_path):
    with pytest.raises(ValueError, match=f"V holds .*{culprit}"):
        symbolic.derive("Box", [q1, q2], T, m * g * term, PARAMS, cache=tmp_path)


def test_complex_numbers_and_explicit_time_are_refused(tmp_path):
    with pytest.raises(ValueError, match="complex"):
        symbolic.derive("Box", [q1, q2], T, sp.I * g * q1, PARAMS, cache=tmp_path)
    with pytest.raises(ValueError, match="time explicitly"):
        symbolic.derive("Box", [q1, q2], T, g * q1 * sp.cos(t), PARAMS, cache=tmp_path)
    with pytest.raises(ValueError, match=r"friction: the law of q1\(t\) holds sign"):
        symbolic.derive("Box", [q1, q2], T, g * q1, PARAMS, friction={q1: sp.sign(q1.diff(t))}, cache=tmp_path)


def test_smooth_elementary_terms_are_taken(tmp_path):
    V = m * g * (sp.cos(q1) + sp.sqrt(1 + q2**2) + sp.atan(q2) + sp.exp(-(q1**2)) + sp.log(2 + sp.cos(q2)))
    model = symbolic.derive("Smooth", [q1, q2], T, V, PARAMS, friction={q1: sp.tanh(q1.diff(t) / 0.01)}, cache=tmp_path)
    assert model.nq == 2


def test_a_posture_at_a_singular_configuration_is_refused_naming_it(tmp_path):
    """``sin(q2) dq1`` in T: the mass matrix is singular at q2 = 0 (the three random samples of derive miss it)."""
    import gymnasium as gym

    from mbs_envs.envs import derived

    T = m * ((sp.sin(q2) * q1.diff(t)) ** 2 + q2.diff(t) ** 2) / 2
    model = symbolic.derive("Singular", [q1, q2], T, m * g * sp.cos(q1), PARAMS, cache=tmp_path)
    derived.register("test/SingularPosture-v0", model, torque_limit=(5.0, 5.0), posture=(0.3, 0.0))
    with pytest.raises(ValueError, match=r"posture: .* singular at q = \[0\.3, 0\.0\]"):
        gym.make("test/SingularPosture-v0")
    derived.register("test/RegularPosture-v0", model, torque_limit=(5.0, 5.0), posture=(0.3, 1.0))
    env = gym.make("test/RegularPosture-v0")
    env.reset(seed=0)
    env.close()
