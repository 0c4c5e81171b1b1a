"""``mbs_envs.simulate``: the simulation entry points, as earlier versions had them here
(they live in :mod:`mbs_envs.dynamics.simulate`; ``mbs_envs.simulate`` is also the function)."""

from .dynamics.simulate import (  # noqa: F401
    DIVERGENCE_LIMIT,
    Input,
    Trajectory,
    acceleration,
    advance,
    diverged,
    input_function,
    simulate,
)
