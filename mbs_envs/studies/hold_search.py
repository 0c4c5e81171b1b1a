"""The search of ``PlannedSwingUp``'s hold on the arm's own map under observation noise (the logic of ``scripts/tune_hold.py``, whose help says what is run and how to read it)."""

from __future__ import annotations

from collections.abc import Callable
import numpy as np
import mbs_envs  # noqa: F401


#: the search's ranges: log10 of the weights (passive angle, driven angle, rates) of each gain, and the edge [rad],
#: lead [s] and way back [rad]
LOG_HOLD, LOG_EDGE, LOG_RECOVER = (
    ((4.5, -1.5, -1.0), (7.5, 1.0, 1.5)),
    ((-2.5, -2.0, 1.0), (1.5, 1.0, 4.0)),
    ((-2.0, -1.0, -3.0), (3.0, 4.5, 2.0)),
)


EDGE, LEAD, BACK = (0.065, 0.09), (0.0, 0.06), (0.04, 0.1)


def draw(rng: np.random.Generator, make: Callable[..., np.ndarray], n: int) -> list[dict]:
    """``n`` candidates whose three gains all exist and stabilize the linearization (``make`` returns them or raises)."""
    out: list[dict] = []
    while len(out) < n:
        w = [10 ** rng.uniform(*bounds) for bounds in (LOG_HOLD, LOG_EDGE, LOG_RECOVER)]
        try:
            K = make(*w)
        except ValueError:
            continue
        out.append({"hold_q": w[0], "edge_q": w[1], "recover_q": w[2], "K": K, "edge": rng.uniform(*EDGE), "edge_lead": rng.uniform(*LEAD),
                    "hold_back": rng.uniform(*BACK)})  # fmt: skip
    return out
