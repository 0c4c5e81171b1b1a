"""docs/tutorial_lagrangian.md: every code block runs, in order (issue 36, item 6)."""

from __future__ import annotations

import pathlib

ROOT = pathlib.Path(__file__).resolve().parents[1]


def test_every_code_block_of_the_lagrangian_tutorial_runs():
    text = (ROOT / "docs" / "tutorial_lagrangian.md").read_text()
    blocks = [b.split("```")[0] for b in text.split("```python")[1:]]
    assert len(blocks) >= 6
    namespace: dict = {}
    for block in blocks:  # later blocks use earlier names
        exec(compile(block, "docs/tutorial_lagrangian.md", "exec"), namespace)
    assert namespace["env"].unwrapped.compiled is not None  # the engine's compiled step on the generated kernels
