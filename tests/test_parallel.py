"""Local worker pools of ``mbs_envs.studies.parallel``: results in order, no orphans."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time

import pytest

from mbs_envs.studies.parallel import run_tasks


def _square(x: int) -> int:
    return x * x


def test_run_tasks_keeps_the_order_of_the_tasks():
    assert run_tasks(_square, [3, 1, 2], max_workers=2) == [9, 1, 4]
    assert run_tasks(_square, [5]) == [25]  # one task: in this process


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGKILL])
def test_workers_end_when_the_study_that_started_them_is_killed(tmp_path, sig):
    """A study killed while its workers compute (the parent gets ``sig``) leaves none running."""
    script = tmp_path / "study.py"
    script.write_text(
        textwrap.dedent(f"""
        import os, pathlib, time
        from mbs_envs.studies.parallel import run_tasks

        def work(k):
            pathlib.Path({str(tmp_path)!r}, f"worker{{k}}.pid").write_text(str(os.getpid()))
            time.sleep(120)

        if __name__ == "__main__":
            run_tasks(work, [0, 1], max_workers=2)
    """)
    )
    study = subprocess.Popen([sys.executable, str(script)], cwd=tmp_path)
    deadline = time.monotonic() + 60
    while len(list(tmp_path.glob("worker*.pid"))) < 2:
        assert time.monotonic() < deadline and study.poll() is None, "the workers did not start"
        time.sleep(0.1)
    pids = [int(p.read_text()) for p in tmp_path.glob("worker*.pid")]
    study.send_signal(sig)
    study.wait(timeout=30)
    deadline = time.monotonic() + 10  # the watch polls every 0.5 s
    alive = pids
    while alive and time.monotonic() < deadline:
        alive = [pid for pid in alive if _running(pid)]
        time.sleep(0.1)
    assert not alive, f"workers {alive} outlived the study"


def _running(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    with open(f"/proc/{pid}/stat") as f:  # a zombie has ended
        return f.read().split(")")[-1].split()[0] != "Z"


def _square(x):
    return x * x


def test_local_tasks_show_progress_and_keep_their_order(capsys):
    """issue 37: the parallel path counts cells as they finish (a tqdm bar on stderr)."""
    from mbs_envs.studies.parallel import run_tasks

    assert run_tasks(_square, list(range(6)), max_workers=2, progress="cells") == [x * x for x in range(6)]
    assert "cells" in capsys.readouterr().err


def _plan_threads(_):
    from mbs_envs.controllers.planned_swingup import plan_threads

    return plan_threads()


def test_pool_workers_plan_on_their_share_of_the_cores(monkeypatch):
    """A worker of a pool that fills the cores plans on its share of them (not every core each: they would only
    contend); a value the user set is kept."""
    import multiprocessing

    monkeypatch.delenv("MBS_ENVS_PLAN_THREADS", raising=False)
    share = max(1, multiprocessing.cpu_count() // 2)
    assert run_tasks(_plan_threads, [0, 1], max_workers=2) == [share, share]
    monkeypatch.setenv("MBS_ENVS_PLAN_THREADS", "3")
    assert run_tasks(_plan_threads, [0, 1], max_workers=2) == [3, 3]
