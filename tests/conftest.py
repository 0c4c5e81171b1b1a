"""The test run compiles each kernel before its first call (``MBS_ENVS_JIT=sync``), as numba does by itself: tests
time, inspect and count compiled code. The background compilation and the kernels' Python, the default for users,
are tested in ``tests/test_background.py``, which sets the mode it tests."""

import os

os.environ.setdefault("MBS_ENVS_JIT", "sync")
