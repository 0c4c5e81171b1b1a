"""Copy trained agents into ``agents/`` without their optimizers' state (:func:`mbs_envs.studies.training.ship`).

``--from`` is a folder written by ``scripts/train.py``: one agent, or one ``seed<k>/`` folder per
training seed (each is shipped to the same name under ``--to``). The weights, configuration,
training log and normalization are kept; the Adam moments (a third to a half of an off-policy
agent's file) are dropped, so all shipped agents stay under their 20 MB budget::

    python scripts/ship_agent.py --from runs/Acrobot-v1/sac --to agents/Acrobot-v1/sac
"""

from __future__ import annotations

import argparse
import pathlib
import sys

from mbs_envs.studies.training import ship


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--from", dest="src", required=True, type=pathlib.Path)
    p.add_argument("--to", dest="dst", required=True, type=pathlib.Path)
    args = p.parse_args(argv)
    seeds = sorted(d for d in args.src.glob("seed*") if (d / "agent.zip").exists())
    pairs = [(d, args.dst / d.name) for d in seeds] or [(args.src, args.dst)]
    if not (pairs[0][0] / "agent.zip").exists():
        raise SystemExit(f"ship_agent.py: no agent.zip in {args.src} or its seed*/ folders")
    for src, dst in pairs:
        size = ship(src, dst)
        print(f"{src} -> {dst}: agent.zip {size / 1e6:.2f} MB (was {(src / 'agent.zip').stat().st_size / 1e6:.2f} MB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
