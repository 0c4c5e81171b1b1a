"""What a run's numbers depend on besides the code: the interpreter, the libraries, the CPU.

The model-based rows are deterministic given these (numpy's reductions are run in a fixed order on a
fixed batch shape; the agents' networks run on one torch thread on the CPU), but floating point differs
between CPU instruction sets and library builds, and a chaotic swing-up episode amplifies a last-bit
difference into a different outcome. The report records this so that two runs can be compared knowing
whether they ran on the same stack.
"""

from __future__ import annotations

import importlib.metadata
import platform
from typing import Any

#: the libraries whose versions the numbers depend on
LIBRARIES = ("numpy", "scipy", "numba", "gymnasium", "control", "torch", "stable-baselines3")
#: the CPU features numpy, numba and torch dispatch on
CPU_FLAGS = ("sse4_2", "avx", "avx2", "fma", "avx512f")


def cpu() -> dict[str, Any]:
    """The CPU's model name and which of :data:`CPU_FLAGS` it has (from ``/proc/cpuinfo``; empty elsewhere)."""
    try:
        text = open("/proc/cpuinfo").read()
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
    return {"python": platform.python_version(), "platform": f"{platform.system()} {platform.machine()}", "cpu": cpu(), "libraries": versions}


def summary_line(rec: dict[str, Any]) -> str:
    """One line for a report: ``Python 3.11.7 on Linux, <cpu> (avx2, fma), numpy 2.x, ...``."""
    libs = ", ".join(f"{k} {v}" for k, v in rec["libraries"].items() if v is not None)
    flags = ", ".join(rec["cpu"]["flags"]) or "none of " + "/".join(CPU_FLAGS)
    return f"Python {rec['python']} on {rec['platform']}, {rec['cpu']['model']} ({flags}); {libs}"
