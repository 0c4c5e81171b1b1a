"""Choosing a DFKI run's checkpoint by the protocol's score (:mod:`mbs_envs.studies.dfki_selection`) and shipping it."""

from __future__ import annotations

import json
import pathlib

import gymnasium as gym
import pytest

from mbs_envs.studies import dfki, dfki_selection as sel
from mbs_envs.studies.training import ALGOS, TrainConfig, load_agent, ship, train


def test_protocol_id_of_every_id_on_the_protocol_plant_and_a_refusal():
    assert (
        sel.protocol_id("mbs_envs/AcrobotDFKI-v2")
        == sel.protocol_id("mbs_envs/AcrobotDFKI-v1")
        == "mbs_envs/AcrobotDFKI-v1"
    )
    assert sel.protocol_id("mbs_envs/PendubotDFKI-v2") == "mbs_envs/PendubotDFKI-v1"
    with pytest.raises(ValueError, match="Acrobot-v2"):
        sel.protocol_id("mbs_envs/Acrobot-v2")


def test_best_takes_the_highest_score_then_the_earliest_checkpoint_then_the_trained_interval():
    rows = [{"checkpoint": 10, "action_repeat": 1, "score": 0.4}, {"checkpoint": 20, "action_repeat": 10, "score": 0.5},
            {"checkpoint": 30, "action_repeat": 1, "score": 0.5}, {"checkpoint": 20, "action_repeat": 1, "score": 0.5}]  # fmt: skip
    assert sel.best(rows) == rows[1]
    assert sel.best([{"checkpoint": 5, "action_repeat": 1, "score": 0.0}]) == {
        "checkpoint": 5,
        "action_repeat": 1,
        "score": 0.0,
    }
    with pytest.raises(ValueError, match="rows"):
        sel.best([])


def test_a_folder_without_a_run_or_checkpoints_is_refused(tmp_path):
    with pytest.raises(ValueError, match="no config.json"):
        sel.checkpoints(tmp_path)
    (tmp_path / "config.json").write_text(json.dumps({"action_repeat": 10}))
    with pytest.raises(ValueError, match="no checkpoints"):
        sel.checkpoints(tmp_path)


@pytest.fixture(scope="module")
def dfki_run(tmp_path_factory) -> pathlib.Path:
    """A few hundred decisions of SAC on the protocol's plant, two checkpoints."""
    out = tmp_path_factory.mktemp("run")
    config = TrainConfig("mbs_envs/PendubotDFKI-v2", "sac", 2000, n_envs=2, action_repeat=10, eval_seeds=1,
                         net_arch=(8, 8), hyper={"learning_starts": 20})  # fmt: skip
    train(config, out, checkpoint_every=1000)
    return out


def test_every_checkpoint_at_each_interval_scored_as_the_protocol_scores_it_and_the_best_shipped(dfki_run, tmp_path):
    assert [s for s, _ in sel.checkpoints(dfki_run)] == [1000, 2000]
    rows = sel.evaluate_run(dfki_run)
    assert [(r["checkpoint"], r["action_repeat"]) for r in rows] == [(1000, 10), (1000, 1), (2000, 10), (2000, 1)]
    # one row recomputed independently: the checkpoint's model, held 10 steps, through the protocol's recording
    from mbs_envs.studies.held import HeldPolicy

    model = ALGOS["sac"].load(dfki_run / "checkpoints" / "agent_200_steps.zip", device="cpu")
    venv = gym.make_vec(
        "mbs_envs/PendubotDFKI-v1", num_envs=1, vectorization_mode="vector_entry_point", autoreset_mode="Disabled"
    )
    p = gym.make("mbs_envs/PendubotDFKI-v1").unwrapped.model.params
    direct = dfki.evaluate(dfki.record(venv, HeldPolicy(model, 10), [0]), p.l1, p.l2)[0]
    assert {k: rows[2][k] for k in sel.COLUMNS} == {k: float(direct[k]) for k in sel.COLUMNS}
    # a (checkpoint, interval) shipped: load_agent gives the policy deciding at that interval, so the shipped agent
    # scores on the protocol exactly what it was chosen with (here the first checkpoint deciding every step)
    ship(dfki_run, tmp_path / "shipped", checkpoint=1000, kept={"by": "test"}, evaluated_action_repeat=1)
    policy, record = load_agent(tmp_path / "shipped")
    assert record["kept"] == {"checkpoint": 1000, "by": "test"} and record["evaluated_action_repeat"] == 1
    assert record["steps"] == 2000  # the budget stays the whole run's
    from mbs_envs.studies.dfki_job import kept_at
    from mbs_envs.studies.learning_curves import read_run

    assert (
        kept_at(read_run(tmp_path / "shipped"))
        == "checkpoint 1,000 of its last run, best protocol score; deciding every 1"
    )
    venv = gym.make_vec(
        "mbs_envs/PendubotDFKI-v1", num_envs=1, vectorization_mode="vector_entry_point", autoreset_mode="Disabled"
    )
    again = dfki.evaluate(dfki.record(venv, policy, [0]), p.l1, p.l2)[0]
    assert {k: float(again[k]) for k in sel.COLUMNS} == {k: rows[1][k] for k in sel.COLUMNS}


def test_ship_refuses_a_checkpoint_the_run_lacks_and_writes_nothing(dfki_run, tmp_path):
    for kw, match in ((dict(checkpoint=1500), "no checkpoint at 1500"), (dict(checkpoint=1005), "no checkpoint"),
                      (dict(kept={"by": "x"}), "only with a checkpoint"),
                      (dict(checkpoint=1000, evaluated_action_repeat=0), "action_repeat")):  # fmt: skip
        with pytest.raises(ValueError, match=match):
            ship(dfki_run, tmp_path / "dst", **kw)
        assert not (tmp_path / "dst").exists()


def test_the_script_writes_its_table_plot_and_ships(dfki_run, tmp_path):
    from tests.test_scripts import load_script

    script = load_script("dfki_select.py")
    result = script["run"](script["parse_args"](["--run", str(dfki_run), "--out", str(tmp_path / "out"),
                                                 "--action-repeats", "10", "--ship", str(tmp_path / "agent")]))  # fmt: skip
    assert [r["action_repeat"] for r in result["rows"]] == [10, 10]
    assert result["best"] == sel.best(result["rows"])
    for name in ("selection.csv", "selection.json", "selection.png"):
        assert (tmp_path / "out" / name).stat().st_size > 0
    record = json.loads((tmp_path / "agent" / "config.json").read_text())
    assert record["kept"]["checkpoint"] == result["best"]["checkpoint"] and record["evaluated_action_repeat"] == 10
    with pytest.raises(ValueError, match="no checkpoints"):
        script["run"](script["parse_args"](["--run", str(tmp_path / "agent"), "--out", str(tmp_path / "o2")]))
    assert not (tmp_path / "o2").exists()


def test_the_script_pins_the_numerics_before_torch_loads():
    """Its scores must be the report's bits (``scripts/dfki.py`` pins MKL's and torch's kernels the same way): the
    script's module does not load torch, and its ``main`` sets the pinned settings before its first import of it."""
    import ast
    import subprocess
    import sys

    from mbs_envs.studies import provenance

    root = pathlib.Path(__file__).resolve().parents[2]
    code = (
        "import os, runpy, sys\n"
        "for k in %r: os.environ.pop(k, None)\n"
        "ns = runpy.run_path(%r, run_name='not_main')\n"
        "assert 'torch' not in sys.modules, 'the module loaded torch'\n"
        "try:\n"
        "    ns['main'](['--run', 'no-such-run', '--out', 'no-such-out'])\n"
        "except ValueError:\n"
        "    pass\n"
        "assert 'torch' in sys.modules\n"
        "print({k: os.environ.get(k) for k in %r})\n"
    ) % (list(provenance.PINNED), str(root / "scripts" / "dfki_select.py"), list(provenance.PINNED))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=root, timeout=300)
    assert out.returncode == 0, out.stderr
    assert ast.literal_eval(out.stdout.strip().splitlines()[-1]) == provenance.PINNED
