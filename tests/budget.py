"""How many generated examples the property tests draw: a third in the default run (its ~5 minute budget on
2 cores), all of them with ``MBS_ENVS_FULL_TESTS=1`` (the nightly-style run: ``MBS_ENVS_FULL_TESTS=1 python -m
pytest -m "slow or not slow"``). The draws are the same strategies either way; only their number changes."""

from __future__ import annotations

import os

FULL = os.environ.get("MBS_ENVS_FULL_TESTS") == "1"


def examples(n: int) -> int:
    """``n`` in the full run, ``max(4, n // 3)`` in the default one."""
    return n if FULL else max(4, n // 3)
