#!/usr/bin/env python
"""Train an SB3 agent on a scene (batched env through the SB3 adapter).

Saves ``agent.zip``, ``config.json`` (env, algorithm, hyperparameters, this
command, training wall time) and ``training_log.csv`` (evaluation error
against training wall time) to ``--out``; optional checkpoints and
tensorboard logs. With several ``--seed`` values the runs go to
``OUT/seed<k>`` and run in parallel processes, or on a Ray cluster with
``--ray [ADDRESS]`` (the ``ray`` extra).

    python scripts/train.py --env mbs_envs/Planar2R-v0 --algo ppo --steps 1000000 --seed 0 --out agents/Planar2R-v0/ppo
    python scripts/train.py --env mbs_envs/SerialChain-v0 --env-kwargs '{"n_links": 5}' --algo sac --steps 100000 --out runs/chain
    python scripts/train.py --env mbs_envs/Acrobot-v0 --algo ppo --hyper gamma=0.998 --steps 5000000 --seed 0 1 2 --out runs/acrobot
    python scripts/train.py --env mbs_envs/FourBar-v0 --algo ppo --residual --steps 2000000 --seed 0 1 2 --out runs/fourbar-res

``--residual [CONTROLLER]`` trains a correction on top of a model-based
controller (default: computed torque; LQR on the disk), bounded by
``--residual-bound`` (a fraction of the actuator limit; see ``mbs_envs.studies.residual``).
"""

from __future__ import annotations

import argparse
import os
import pathlib
import sys

# every core busy with this script's processes: kernels compile before they run (mbs_envs/dynamics/background.py)
os.environ.setdefault("MBS_ENVS_JIT", "sync")

import mbs_envs  # noqa: F401
from mbs_envs.studies import cli
from mbs_envs.envs import registry
from mbs_envs.envs.presets import PROTOCOL_IDS, TRAINING_IDS
from mbs_envs.studies.swingup_starts import swingup_starts
from mbs_envs.studies.evaluation import ERROR_METRIC
from mbs_envs.studies.parallel import run_tasks
from mbs_envs.studies.training import ALGOS, TrainConfig, hyper_setting, out_refusal, residual_base, train


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--env", required=True, choices=list(mbs_envs.ENV_IDS) + [e[0] for e in PROTOCOL_IDS + TRAINING_IDS])
    p.add_argument("--algo", required=True, choices=sorted(ALGOS))
    p.add_argument("--steps", required=True, type=cli.positive_int)
    p.add_argument("--seed", type=int, nargs="+", default=[0])
    p.add_argument("--out", required=True, type=cli.out_folder)
    p.add_argument("--n-envs", type=cli.positive_int, help="parallel members (default 64 for PPO, 4 otherwise)")
    p.add_argument("--env-kwargs", type=cli.json_object, default={}, help="JSON dict of env arguments")
    p.add_argument(
        "--keep-best",
        action="store_true",
        help="ship the agent of the best validation (fewest failed episodes, then highest return), not the last",
    )
    p.add_argument(
        "--train-env-kwargs",
        type=cli.json_object,
        default={},
        help="JSON dict of env arguments for the training members only (a curriculum; validation runs the task as "
        "--env-kwargs gives it), e.g. '{\"start_upright\": 0.5}'",
    )
    p.add_argument(
        "--starts-from-plan",
        type=float,
        metavar="SHARE",
        help="a curriculum on a swing-up id: this share of the training episodes that would start hanging starts from "
        "a state of the scene's best model-based swing-up instead (the score-designed plan on the DFKI protocol's "
        "plant, identified iLQR + TVLQR on our own arms; added to --train-env-kwargs as start_states)",
    )
    p.add_argument(
        "--eval-env-kwargs",
        type=cli.json_object,
        default={},
        help='JSON dict of env arguments for the validation episodes only, e.g. \'{"randomize": {"m2": 0.25}}\' '
        "(each validation seed's plant drawn from it; --keep-best then keeps the best over those plants)",
    )
    p.add_argument(
        "--net-arch", type=int, nargs="+", help="hidden layers (default SB3's: 64 64 for PPO, 256 256 otherwise)"
    )
    p.add_argument(
        "--residual",
        nargs="?",
        const="default",
        help="train a residual agent on this controller ('module:Class'; default the scene's best)",
    )
    p.add_argument(
        "--residual-bound",
        type=float,
        default=0.25,
        help="largest correction, fraction of the actuator limit (default 0.25)",
    )
    p.add_argument(
        "--hyper",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        type=hyper_setting,
        help="override a numeric hyperparameter, e.g. --hyper gamma=0.998 (repeatable)",
    )
    p.add_argument(
        "--action-repeat",
        type=cli.positive_int,
        default=1,
        metavar="K",
        help="hold each action for K control steps (the agent decides every K dt; default 1)",
    )
    p.add_argument(
        "--normalize",
        action="store_true",
        help="train behind VecNormalize (observations and rewards); the statistics are saved with the agent",
    )
    p.add_argument(
        "--perturb",
        type=lambda t: t if t == "dfki" else cli.json_object(t),
        help="train under the robustness axes, one perturbation per member and episode: 'dfki' (the DFKI "
        "benchmark's ranges) or a JSON dict of mbs_envs.envs.perturbed.TrainingPerturbations' fields",
    )
    p.add_argument(
        "--init",
        type=pathlib.Path,
        help="continue the agent saved in this folder (e.g. one of an earlier task version) or one of its checkpoints (FOLDER/checkpoints/agent_<n>_steps.zip); {seed} stands for the run seed",
    )
    p.add_argument(
        "--eval-seeds", type=cli.positive_int, default=10, help="validation episodes per evaluation (default 10)"
    )
    p.add_argument("--eval-every", type=cli.positive_int, help="env-steps between evaluations (default steps/10)")
    p.add_argument("--checkpoint-every", type=cli.positive_int, help="env-steps between checkpoints")
    p.add_argument("--tensorboard", action="store_true")
    p.add_argument(
        "--overwrite",
        action="store_true",
        help="replace an agent already in --out (a folder another run is writing is refused)",
    )
    p.add_argument(
        "--smooth",
        metavar="T,S,SIGMA",
        help="CAPS smoothness regularization of an off-policy actor: the temporal and spatial terms' weights and the "
        "observation noise (mbs_envs.studies.smoothing), e.g. 1,1,0.05",
    )
    p.add_argument(
        "--ray", nargs="?", const="local", help="run the seeds on Ray (cluster ADDRESS, or a local instance)"
    )
    return p.parse_args(argv)


def _train_one(task: dict) -> dict:
    config = TrainConfig(**task["config"])
    return train(config, pathlib.Path(task["out"]), task["tensorboard"], task["checkpoint_every"], task["overwrite"])


def run(args: argparse.Namespace) -> list[dict]:
    tasks = []
    residual = residual_base(args.env) if args.residual == "default" else args.residual
    train_env_kwargs = dict(args.train_env_kwargs)
    if args.starts_from_plan is not None:
        try:
            train_env_kwargs["start_states"] = swingup_starts(
                args.env, args.starts_from_plan, env_kwargs=args.env_kwargs
            )
        except ValueError as exc:
            raise SystemExit(f"train.py: --starts-from-plan: {exc}") from None
    for seed in args.seed:
        config = dict(env_id=args.env, algo=args.algo, steps=args.steps, seed=seed, n_envs=args.n_envs,
                      env_kwargs=args.env_kwargs, train_env_kwargs=train_env_kwargs, eval_env_kwargs=args.eval_env_kwargs, keep_best=args.keep_best, net_arch=tuple(args.net_arch) if args.net_arch else None,
                      eval_every=args.eval_every, eval_seeds=args.eval_seeds, residual=residual, residual_bound=args.residual_bound,
                      hyper=dict(args.hyper), action_repeat=args.action_repeat, normalize=args.normalize, perturb=args.perturb,
                      init=str(args.init).format(seed=seed) if args.init else None, smooth=args.smooth)  # fmt: skip
        try:
            TrainConfig(**config)  # validate before starting anything
        except ValueError as exc:
            raise SystemExit(f"train.py: {exc}") from None
        out = args.out if len(args.seed) == 1 else args.out / f"seed{seed}"
        refusal = out_refusal(out, args.overwrite)
        if refusal:
            raise SystemExit(f"train.py: {refusal} (--overwrite replaces an agent)")
        tasks.append({"config": config, "out": str(out), "tensorboard": args.tensorboard, "checkpoint_every": args.checkpoint_every,
                      "overwrite": args.overwrite})  # fmt: skip
    records = run_tasks(_train_one, tasks, ray_address=args.ray)
    for task, r in zip(tasks, records):
        e = r["final_evaluation"]
        metric = ERROR_METRIC[registry.scene(r["env_id"]).scoring]  # of the episodes that did not fail
        print(f"{task['out']}: {r['algo']} {r['env_id']} seed {r['seed']}: {r['train_wall_s']:.0f} s, "
              f"{metric} {e[metric]:.3g}, return {e['return']:.1f}, failures {e['failure_rate']:.0%}")  # fmt: skip
    return records


def main(argv: list[str] | None = None) -> int:
    run(parse_args(argv))
    return 0


if __name__ == "__main__":
    sys.exit(main())
