"""The generated parts of the README and the documentation: written from the code and the committed reports.

- the README's environments table (:func:`mbs_envs.studies.catalogue.environments_table`) and its results at a
  glance (:mod:`mbs_envs.studies.glance`), between ``<!-- glance:NAME -->`` markers;
- one documentation page per registered id, ``docs/environments/<id>.md``
  (:func:`mbs_envs.studies.catalogue.env_page`), and their index;
- the gallery page, ``docs/gallery.md``, from the gallery's own index.

:func:`generate` returns every generated file's text; :func:`stale` names the files on disk that differ from it
(what ``scripts/readme.py --check`` and the tests report); :func:`write` writes them.
"""

from __future__ import annotations

import pathlib

from . import catalogue, glance

#: where each environment's gallery animation lives (relative to the repository), if it has one
GALLERY = "docs/gallery"
PAGES = "docs/environments"


def _gif(root: pathlib.Path, slug: str) -> str | None:
    """The gallery animation of the id ``slug`` (a path relative to its page), if there is one."""
    hits = sorted((root / GALLERY).glob(f"{slug}_*.gif"))
    return f"../gallery/{hits[0].name}" if hits else None


def index_page(facts: list[catalogue.EnvFacts]) -> str:
    """The environments' index page: the table and the toctree of the pages."""
    table = catalogue.environments_table(facts, link="{slug}.md")
    toc = "\n".join(f.slug for f in facts)
    return (
        f"# Environments\n\nEvery id registers with `import mbs_envs`; each page below is generated from the env "
        f"class's docstring (`python scripts/readme.py`).\n\n{table}\n\n```{{toctree}}\n:hidden:\n\n{toc}\n```\n"
    )


def gallery_page(root: pathlib.Path) -> str:
    """The gallery page, from the index ``scripts/record.py --gallery`` writes (``docs/gallery/gallery.json``)."""
    import json

    index = json.loads((root / GALLERY / "gallery.json").read_text())
    lines = ["# Gallery", "",
             "Each scene's best model-based controller (left) beside PPO (right, training seed 0) on test seed 0, recorded",
             "with `python scripts/record.py --gallery --out docs/gallery`. Captions give the time and the error; orange",
             "arcs are the applied torques scaled to the limit; faint, the reference or the upright pose.", ""]  # fmt: skip
    for env_id, record in index.items():
        slug = env_id.split("/", 1)[1]
        labels = " (left), ".join(p["label"] for p in record["panels"]) + " (right)"
        lines += [f"## {slug}", "", f"![{env_id}](gallery/{pathlib.Path(record['file']).name})", "",
                  f"{labels}; the environment's [page](environments/{slug}.md).", ""]  # fmt: skip
    return "\n".join(lines).rstrip() + "\n"


def generate(root: pathlib.Path) -> dict[pathlib.Path, str]:
    """Every generated file (path under ``root`` -> text), the README with its blocks filled."""
    facts = [catalogue.env_facts(i) for i in catalogue.registered_ids()]
    blocks = {"environments": catalogue.environments_table(facts), **glance.tables(root)}
    out = {root / "README.md": glance.fill((root / "README.md").read_text(), blocks)}
    out[root / PAGES / "index.md"] = index_page(facts)
    out[root / "docs" / "gallery.md"] = gallery_page(root)
    for f in facts:
        out[root / PAGES / f"{f.slug}.md"] = catalogue.env_page(f, _gif(root, f.slug))
    return out


def stale(root: pathlib.Path) -> list[pathlib.Path]:
    """The generated files that are missing or differ from :func:`generate`, and stray pages."""
    files = generate(root)
    bad = [p for p, text in files.items() if not p.exists() or p.read_text() != text]
    bad += [p for p in sorted((root / PAGES).glob("*.md")) if p not in files]
    return bad


def write(root: pathlib.Path) -> list[pathlib.Path]:
    """Write every generated file that changed (and remove stray pages); returns those written."""
    (root / PAGES).mkdir(parents=True, exist_ok=True)
    changed = []
    files = generate(root)
    for p, text in files.items():
        if not p.exists() or p.read_text() != text:
            p.write_text(text)
            changed.append(p)
    for p in sorted((root / PAGES).glob("*.md")):
        if p not in files:
            p.unlink()
            changed.append(p)
    return changed
