"""Our swing-up controllers on the DFKI double-pendulum benchmark (RealAIGym), beside its leaderboards.

The protocol (``mbs_envs/AcrobotDFKI-v1``, ``mbs_envs/PendubotDFKI-v1``: the identified design C.1
plant, 6 N m, RK4 at 2 ms, 10 s from hanging at rest) runs every model-based swing-up controller once, and
every agent trained on the protocol (``agents/<scene>DFKI-v1/<algo>/seed<k>/``) alone and with the plant's
upright LQR catching, and scores each with the benchmark's success rule and simulation-v2 score
(``mbs_envs/studies/dfki.py``);
``--robustness`` adds its robustness-v2 sweep (six axes, each a batched rollout; a model-based controller's cut in
parts of ``--part-size`` members, every part seeing the noise it sees in the whole batch:
:func:`mbs_envs.studies.dfki.sweep_parts`; an agent's one batch per axis, as its network's outputs move in the last
bits with the batch size). The
controllers' episodes and the parts of every sweep run in one pool of processes (``--workers``), or on Ray with
``--ray [ADDRESS]`` (the ``ray`` extra); the wall time is printed and kept in ``dfki.json``. Writes
``dfki.csv``, ``dfki.json``, ``report.md`` (our rows beside the published ones), one time-series plot per
controller and one robustness plot per scene to ``--out``::

    python scripts/dfki.py --out results/dfki                      # the protocol: about a minute
    python scripts/dfki.py --out results/dfki --robustness         # and the sweep: minutes per controller
    python scripts/dfki.py --out results/dfki_tune --tune --write  # tune the energy controllers on the protocol
    python scripts/dfki.py --out results/dfki_catch --tune-robust-catch --write   # the catching LQR, for robustness
    python scripts/dfki.py --out results/dfki_release --tune-robust-catch --release-stage --write   # its hand-back factor
    python scripts/dfki.py --out results/dfki_rc --robustness --robust-catch     # the policies with that catch

The energy controllers run with the gains tuned on the protocol where ``controllers/tuned.json`` has them (``--tune``:
:mod:`mbs_envs.studies.dfki_tuning`, 8-9 minutes per scene on one core in the last run; ``--write`` stores the picks), else with those tuned on our own
scene of the same task (``mbs_envs/<scene>-v1``).

``--tune-robust-catch`` tunes the catching LQR (its input weight and catch level) of every policy that has one -- the
energy controllers and each agent with the LQR catching, an agent's training seeds together -- for robustness, on a
tuning set of the robustness axes drawn apart from the benchmark's grid (:func:`mbs_envs.studies.dfki_tuning.robust_catch`);
``--write`` stores the picks as ``"<name> (robust catch)"`` under the protocol ids, and ``--robust-catch`` runs those
policies with them (their names get ``" (robust catch)"``), to be scored on the benchmark's own grid. With
``--release-stage`` it is the second stage: each stored pick kept, the factor on its level beyond which the LQR hands
back (``release``) tried by the same rule, the pick stored in the same entry.
"""

from __future__ import annotations

import argparse
import os
import pathlib
import sys

os.environ.setdefault("MBS_ENVS_JIT", "sync")

import mbs_envs  # noqa: E402,F401  (registers the ids)
from mbs_envs.studies.dfki_job import SCENES, check_args, run, tune, tune_robust_catch  # noqa: E402
from mbs_envs.studies import dfki, provenance  # noqa: E402,F401


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", required=True, type=pathlib.Path)
    p.add_argument("--scene", action="append", choices=sorted(SCENES), help="scene(s) (default both)")
    p.add_argument(
        "--controller",
        action="append",
        help="controller(s) or agent(s) by name, e.g. 'swing-up + LQR', 'PPO seed0' (default every one)",
    )
    p.add_argument(
        "--agents",
        type=pathlib.Path,
        default=pathlib.Path("agents"),
        help="root of the agents trained on the protocol plant (<root>/<scene>DFKI-v<k>/<algo>/seed<j>/; default agents/)",
    )
    p.add_argument("--no-agents", action="store_true", help="the model-based controllers only")
    p.add_argument("--no-controllers", action="store_true", help="the agents only")
    p.add_argument("--robustness", action="store_true", help="run the robustness-v2 sweep too")
    p.add_argument(
        "--values",
        type=int,
        default=dfki.N_VALUES,
        help=f"values per robustness axis (default {dfki.N_VALUES}, as theirs)",
    )
    p.add_argument("--seed", type=int, default=0, help="seeds the sweep's noise and pulses")
    p.add_argument(
        "--part-size",
        type=int,
        default=None,
        help="members per part of a model-based controller's sweep (default: about 4 parts per worker over "
        "their sweeps, at most 32 members; an agent's sweep runs one batch per axis)",
    )
    p.add_argument(
        "--workers", type=int, default=None, help="local processes (default: one per core, at most one per controller)"
    )
    p.add_argument(
        "--ray",
        nargs="?",
        const="local",
        default=None,
        help="run the controllers on Ray (cluster ADDRESS, or a local instance)",
    )
    p.add_argument(
        "--rates-from-angles",
        action="store_true",
        help="every policy sees the joint rates differenced from the observed angles instead of the observed "
        "rates (controllers.estimator.RatesFromAngles); their names get ' (rates from angles)'",
    )
    p.add_argument(
        "--robust-catch",
        action="store_true",
        help="run only the policies with a catching LQR tuned for robustness (--tune-robust-catch --write), with it; "
        "their names get ' (robust catch)'",
    )
    p.add_argument(
        "--tune",
        action="store_true",
        help="tune the energy controllers' gains on the protocol instead (mbs_envs.studies.dfki_tuning)",
    )
    p.add_argument(
        "--tune-robust-catch",
        action="store_true",
        help="tune the catching LQR of every policy that has one for robustness instead, on a tuning set of the "
        "robustness axes (mbs_envs.studies.dfki_tuning.robust_catch; with --rates-from-angles as the policies "
        "will run)",
    )
    p.add_argument(
        "--release-stage",
        action="store_true",
        help="with --tune-robust-catch: its second stage, each stored robust catch's lqr_r and catch kept and the factor "
        "'release' (the LQR hands back beyond release x catch) tried (mbs_envs.studies.dfki_tuning.release_grid)",
    )
    p.add_argument(
        "--release-values",
        type=float,
        nargs="+",
        help="with --release-stage: the factors tried, in this order (a tie keeps the first; default "
        "dfki_tuning.ROBUST_RELEASE), e.g. a grid widened beyond a pick at its edge",
    )
    p.add_argument(
        "--write",
        action="store_true",
        help="with --tune or --tune-robust-catch: store the picks in controllers/tuned.json under the protocol ids",
    )
    return p.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    provenance.pin_numerics()  # before torch loads, here and in the workers (mbs_envs/studies/provenance.py)
    args = parse_args(argv)
    check_args(args)
    (tune if args.tune else tune_robust_catch if args.tune_robust_catch else run)(args)
    return 0


if __name__ == "__main__":
    sys.exit(main())
