"""The README and the documentation as a user reads them: generated parts current, links resolving, no history."""

import json
import pathlib
import re

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
DOC_PAGES = sorted((ROOT / "docs").glob("*.md")) + sorted((ROOT / "docs" / "environments").glob("*.md"))

#: development history a user must not read as current: numbered steps, issue numbers, run logs, the CPU of the day
HISTORY = re.compile(
    r"\b[Ss]ession \d+|\b[Ii]ssues? \d+|\bthe run before\b|\b20\d\d-\d\d-\d\d\b|\bXeon\b|\bEPYC\b"
    r"|scenes_s\d+|\bcommit [0-9a-f]{7}\b"
)


def test_the_readme_is_an_overview_with_the_install_first():
    lines = README.read_text().splitlines()
    assert len(lines) <= 250
    first_install = next(i for i, line in enumerate(lines) if line.lstrip().startswith("pip install"))
    assert first_install < 40
    commands = [line for line in lines if line.startswith("pip install torch==2.13.0 && pip install -e")]
    assert len(commands) == 2 and commands[1].endswith("python -m pytest -q")  # the two commands, CI runs the second


def test_the_generated_parts_equal_what_the_code_and_the_reports_give():
    """README's environments table and results at a glance, every environment page: ``scripts/readme.py``."""
    from mbs_envs.studies import generated

    assert generated.stale(ROOT) == []


def test_the_environments_table_lists_exactly_the_registered_ids():
    import gymnasium as gym

    import mbs_envs  # noqa: F401

    block = README.read_text().split("<!-- glance:environments -->")[1].split("<!-- /glance:environments -->")[0]
    listed = re.findall(r"\[`(mbs_envs/[^`]+)`\]", block)
    registered = [i for i in gym.registry if i.startswith("mbs_envs/")]
    assert sorted(listed) == sorted(registered) and len(listed) == len(set(listed)) == 18
    for i in registered:
        assert (ROOT / "docs" / "environments" / f"{i.split('/', 1)[1]}.md").exists(), i


def test_the_results_tables_are_the_committed_reports():
    """A figure changed by hand in the README, or a report changed without the README, fails here."""
    from mbs_envs.studies import glance

    text = README.read_text()
    tables = glance.tables(ROOT)
    for name, table in tables.items():
        assert f"<!-- glance:{name} -->\n{table}\n<!-- /glance:{name} -->" in text, name
    summary = json.loads((ROOT / glance.COMPARE).read_text())
    computed = summary["summary"]["Planar2R"]["nominal"]["computed torque"]["rms_error_settled"]
    assert f"{computed:.3g}" in tables["tracking"]  # the table reads the report, not a constant


def test_the_pure_rl_table_leaves_out_the_lqr_catching_and_compares_with_published_rl_only():
    from mbs_envs.studies import glance

    agents = {"rows": [{"scene": "Acrobot", "controller": "SAC seed0", "score": 0.3},
                       {"scene": "Acrobot", "controller": "SAC + CAPS seed0", "score": 0.5},
                       {"scene": "Acrobot", "controller": "SAC + CAPS + LQR seed0", "score": 0.9}],
              "sweeps": {"Acrobot | SAC + CAPS seed0": {"score": {"value": 0.61}}}}  # fmt: skip
    row = glance.dfki_rl_table(agents).splitlines()[2]
    assert (
        row == "| Acrobot | SAC + CAPS seed0 | 0.500 | 0.610 | History SAC | 0.655 | History SAC | 0.751 |"
    )  # not TVLQR


def test_fill_refuses_missing_markers():
    from mbs_envs.studies import glance

    with pytest.raises(ValueError, match="'dfki'"):
        glance.fill("no markers", {"dfki": "| x |"})
    assert glance.fill("a\n<!-- glance:x -->\nold\n<!-- /glance:x -->\nb", {"x": "new"}) == (
        "a\n<!-- glance:x -->\nnew\n<!-- /glance:x -->\nb"
    )


@pytest.mark.parametrize("page", [README, *DOC_PAGES], ids=lambda p: str(p.relative_to(ROOT)))
def test_every_local_link_and_image_resolves(page):
    text = re.sub(r"```.*?```", "", page.read_text(), flags=re.S)
    for target in re.findall(r"\]\(([^)\s]+)\)", text):
        if re.match(r"[a-z]+://|#|mailto:", target):
            continue
        path = (page.parent / target.split("#")[0]).resolve()
        assert path.exists(), f"{page.name}: {target}"


@pytest.mark.parametrize("page", [README, *DOC_PAGES], ids=lambda p: str(p.relative_to(ROOT)))
def test_no_development_history_in_what_users_read(page):
    hits = HISTORY.findall(page.read_text())
    assert not hits, f"{page.name}: {hits}"


def test_no_development_history_in_the_reports_the_docs_include():
    """A report a page includes is read as the page; its provenance line (``Run on: ...``) may say when and where."""
    included = {
        (page.parent / m).resolve()
        for page in DOC_PAGES
        for m in re.findall(r"```\{include\} (\S+)", page.read_text())
        if (page.parent / m).suffix == ".md" and "CHANGELOG" not in m
    }
    assert included  # the benchmarks and performance pages include reports
    hits = {}
    for path in sorted(included):
        text = "\n".join(line for line in path.read_text().splitlines() if not line.startswith("Run on:"))
        if HISTORY.findall(text):
            hits[str(path.relative_to(ROOT))] = HISTORY.findall(text)
    assert not hits, hits


def test_no_development_history_in_docstrings_script_help_or_shipped_json():
    import subprocess

    files = subprocess.run(["git", "ls-files", "mbs_envs", "controllers", "scripts", "agents"], cwd=ROOT,
                           capture_output=True, text=True, check=True).stdout.split()  # fmt: skip
    files = [f for f in files if f.endswith((".py", "config.json"))] + ["controllers/tuned.json"]
    hits = {}
    for f in files:
        text = (ROOT / f).read_text()
        if f.endswith(".py"):  # docstrings and comments (script help is the module docstring)
            text = "\n".join(re.findall(r'"""(.*?)"""', text, flags=re.S) + re.findall(r"#.*", text))
        found = [h for h in HISTORY.findall(text) if not h.startswith("2024-")]  # a publication's release date
        if found:
            hits[f] = found
    assert not hits, hits


def test_no_committed_result_holds_an_absolute_path_of_the_machine_that_made_it():
    import subprocess

    files = subprocess.run(["git", "ls-files", "docs/figures", "agents", "controllers"], cwd=ROOT,
                           capture_output=True, text=True, check=True).stdout.split()  # fmt: skip
    pattern = re.compile(r"(?<![\w.])/(?:tmp|work|root|home|Users)/")
    bad = [f for f in files if f.endswith((".json", ".csv", ".md")) and pattern.search((ROOT / f).read_text())]
    assert not bad, bad
