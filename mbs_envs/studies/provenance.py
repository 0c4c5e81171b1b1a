"""What a run's numbers depend on besides the code: the interpreter, the libraries, the CPU.

The model-based rows are deterministic given these (numpy's reductions are run in a fixed order on a
fixed batch shape; the agents' networks run on one torch thread on the CPU), but floating point differs
between CPU instruction sets and library builds, and a chaotic swing-up episode amplifies a last-bit
difference into a different outcome. The report records this so that two runs can be compared knowing
whether they ran on the same stack.

What can be pinned is pinned (:func:`pin_numerics`, called by the evaluation scripts before torch is loaded).
Emulating a CPU without AVX-512 on one with it, one knob at a time (two scenes of the main job, 450 summary
values): numpy without its AVX-512 loops, OpenBLAS's Haswell kernels and numba compiling for Haswell each
changed none of them; Intel MKL's code path (``MKL_CBWR=AVX2`` against its AVX-512 default) changed 96, all
of them the agents' (their networks' matrix products, in the last bits, amplified by the closed loop).
MKL in its compatible mode computes the same bits on every x86-64 CPU, Intel's or not.
"""

from __future__ import annotations

import importlib.metadata
import os
import pathlib
import platform
import shlex
import sys
from typing import Any

#: the libraries whose versions the numbers depend on
LIBRARIES = ("numpy", "scipy", "numba", "gymnasium", "control", "torch", "stable-baselines3")
#: the CPU features numpy, numba and torch dispatch on
CPU_FLAGS = ("sse4_2", "avx", "avx2", "fma", "avx512f")
#: what :func:`pin_numerics` sets: Intel MKL's conditional numerical reproducibility in its mode for every
#: x86-64 CPU (the agents' matrix products; measured, module docstring), and torch's own kernels at the AVX2
#: level on every CPU that has it (a guard: they changed no value in the same measurement)
PINNED = {"MKL_CBWR": "COMPATIBLE", "ATEN_CPU_CAPABILITY": "avx2"}


def pin_numerics() -> dict[str, str]:
    """Put :data:`PINNED` into the environment, where not set already, so that this process and the workers it
    starts compute the agents' actions with the same bits on any x86-64 CPU; the settings in force.

    Raises
    ------
    RuntimeError
        If torch is already imported (MKL and torch read these when they load).
    """
    if "torch" in sys.modules:
        raise RuntimeError(
            "pin_numerics() must run before torch is imported: MKL and torch read their settings when they load"
        )
    for name, value in PINNED.items():
        os.environ.setdefault(name, value)
    return {name: os.environ[name] for name in PINNED}


def cpu() -> dict[str, Any]:
    """The CPU's model name and which of :data:`CPU_FLAGS` it has (from ``/proc/cpuinfo``; empty elsewhere)."""
    try:
        text = pathlib.Path("/proc/cpuinfo").read_text()
    except OSError:
        return {"model": platform.processor() or "unknown", "flags": []}
    info = dict(line.split(":", 1) for line in text.splitlines()[:40] if ":" in line)
    model = next((v.strip() for k, v in info.items() if k.strip() == "model name"), "unknown")
    flags = set(next((v.split() for k, v in info.items() if k.strip() == "flags"), []))
    return {"model": model, "flags": [f for f in CPU_FLAGS if f in flags]}


def record() -> dict[str, Any]:
    """Python, platform, CPU and library versions (a library that is not installed: None)."""
    versions = {}
    for name in LIBRARIES:
        try:
            versions[name] = importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:
            versions[name] = None
    pinned = {name: os.environ.get(name) for name in PINNED}
    return {"python": platform.python_version(), "platform": f"{platform.system()} {platform.machine()}", "cpu": cpu(), "libraries": versions,
            "pinned": pinned}  # fmt: skip


def summary_line(rec: dict[str, Any]) -> str:
    """One line for a report: ``Python 3.11.7 on Linux, <cpu> (avx2, fma), numpy 2.x, ...``."""
    libs = ", ".join(f"{k} {v}" for k, v in rec["libraries"].items() if v is not None)
    flags = ", ".join(rec["cpu"]["flags"]) or "none of " + "/".join(CPU_FLAGS)
    pinned = ", ".join(f"{k}={v}" for k, v in rec.get("pinned", {}).items() if v is not None) or "nothing pinned"
    return f"Python {rec['python']} on {rec['platform']}, {rec['cpu']['model']} ({flags}); {libs}; {pinned}"


def command_line(script: str) -> str | None:
    """The command this process was started with, ``"python scripts/<script> ..."`` with its arguments quoted for a
    POSIX shell (a JSON argument pastes back as it was given), or None when not run as ``script``."""
    if not (sys.argv and sys.argv[0].endswith(script)):
        return None
    return f"python scripts/{script} {shlex.join(sys.argv[1:])}".rstrip()
