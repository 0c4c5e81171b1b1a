"""The catalogue of registered environments: what the README's table and the docs' pages show of each id.

Every fact comes from the code: the id's registration (entry point, episode length), an env made from it
(observation and action spaces), the scene registry (the model-based baselines) and the env class's
docstring, whose ``## Section`` blocks are merged along the class hierarchy (a subclass's section replaces
its base's of the same name), as Gymnasium's ``docs/_scripts/gen_mds.py`` builds its pages from the class
docstrings.
"""

from __future__ import annotations

import dataclasses
import inspect
import re

import gymnasium as gym

from ..envs import registry
from ..envs.presets import PROTOCOL_IDS, TRAINING_IDS

#: the sections of an environment page, in Gymnasium's order
SECTIONS = ("Description", "Action Space", "Drives", "Observation Space", "Rewards", "Starting State", "Episode End",
            "Arguments", "Rendering", "Version History", "References")  # fmt: skip

#: the protocol ids' one-line summaries (mechanism: task), beside the preset they apply
PROTOCOL_SUMMARY = {
    "mbs_envs/AcrobotDFKI-v1": "DFKI double pendulum (design C.1, model 1.0), elbow driven at 6 N m: "
    "swing up from hanging and balance, the leaderboard's simulation protocol (RK4 at 2 ms, 10 s)",
    "mbs_envs/PendubotDFKI-v1": "DFKI double pendulum (design C.1, model 1.0), shoulder driven at 6 N m: "
    "swing up from hanging and balance, the leaderboard's simulation protocol (RK4 at 2 ms, 10 s)",
    "mbs_envs/AcrobotDFKI-v2": "DFKI double pendulum (design C.1, model 1.0), elbow driven at 6 N m: "
    "the protocol's plant and setup with the v2 reward (the LQR region's), to train on",
    "mbs_envs/PendubotDFKI-v2": "DFKI double pendulum (design C.1, model 1.0), shoulder driven at 6 N m: "
    "the protocol's plant and setup with the v2 reward (the LQR region's), to train on",
}


@dataclasses.dataclass(frozen=True)
class EnvFacts:
    """What the catalogue shows of one registered id.

    Attributes
    ----------
    id : str
        Gymnasium id.
    entry_point : str
        ``"module:Class"`` of the env.
    max_episode_steps : int
        Truncation of the registered id.
    dt : float
        Control step [s].
    observation_shape, action_shape : tuple of int
        The spaces' shapes.
    observation_space, action_space : str
        The spaces as Gymnasium writes a ``Box`` of uniform bounds.
    mechanism, task : str
        The summary line of the docstring, split at its first colon.
    baselines : tuple of str
        The model-based controllers the comparison runs on the scene.
    kwargs : dict
        The registration's keywords (a preset for the protocol ids).
    sections : dict
        Section title -> Markdown body, in :data:`SECTIONS` order.
    """

    id: str
    entry_point: str
    max_episode_steps: int
    dt: float
    observation_shape: tuple
    action_shape: tuple
    observation_space: str
    action_space: str
    mechanism: str
    task: str
    baselines: tuple
    kwargs: dict
    sections: dict

    @property
    def slug(self) -> str:
        """The page's file stem: the id without the namespace (``Planar2R-v0``)."""
        return self.id.split("/", 1)[1]


def to_markdown(rst: str) -> str:
    """A docstring's inline reStructuredText as Markdown: ````x```` -> ```x```, ``:class:`~a.b.C``` -> ```C```."""
    text = re.sub(
        r":(?:class|func|meth|mod|data|attr|obj):`~?([^`]+)`", lambda m: f"`{m.group(1).split('.')[-1]}`", rst
    )
    return text.replace("``", "`")


def split_sections(doc: str) -> tuple[str, dict[str, str]]:
    """A docstring's summary (before the first ``## `` heading) and its sections by title.

    A numpydoc ``Parameters`` block after the sections is left out (the page shows ``## Arguments``).
    """
    doc = re.split(r"\n(?:Parameters|Attributes)\n-{4,}\n", doc)[0]
    parts = re.split(r"^## +(.+?)\s*$", doc, flags=re.M)
    sections = {parts[i].strip(): parts[i + 1].strip() for i in range(1, len(parts) - 1, 2)}
    return parts[0].strip(), sections


def merged_sections(cls: type) -> tuple[str, dict[str, str]]:
    """The summary of ``cls`` and the sections of its docstring merged along its bases (nearest class wins).

    The intro text of a class's docstring (after its summary line, before its first section) opens its
    Description when it has no ``## Description`` of its own.
    """
    from ..envs.base import MBSEnv

    summary, merged = "", {}
    for klass in reversed(cls.__mro__):
        if not (isinstance(klass, type) and issubclass(klass, MBSEnv)) or klass is MBSEnv:
            continue
        doc = klass.__dict__.get("__doc__")
        if not doc:
            continue
        head, sections = split_sections(inspect.cleandoc(doc))
        summary = head.split("\n\n")[0].replace("\n", " ")
        merged.update(sections)
    return summary, {name: merged[name] for name in SECTIONS if name in merged}


def _baselines(env_id: str) -> tuple[str, ...]:
    base_id = {pid: next(s.id for s in registry.SCENES if s.entry_point == entry)
               for pid, entry, _, _ in PROTOCOL_IDS + TRAINING_IDS}  # fmt: skip
    extra = tuple(registry.PROTOCOL_CONTROLLERS) if env_id in base_id else ()
    return tuple(registry.scene(base_id.get(env_id, env_id)).controllers) + extra


def box_text(space: gym.spaces.Box) -> str:
    """``Box(low, high, shape, dtype)`` with scalar bounds where they are uniform."""
    import numpy as np

    def bound(b):
        return f"{float(b.flat[0]):g}" if np.all(b == b.flat[0]) else "..."

    return f"Box({bound(space.low)}, {bound(space.high)}, {space.shape}, {space.dtype})"


def env_facts(env_id: str) -> EnvFacts:
    """The facts of ``env_id`` (makes the env once to read its spaces and step)."""
    spec = gym.spec(env_id)
    env = gym.make(env_id)
    try:
        obs_shape, act_shape = env.observation_space.shape, env.action_space.shape
        spaces = box_text(env.observation_space), box_text(env.action_space)
        dt = float(env.unwrapped.dt)
        cls = type(env.unwrapped)
    finally:
        env.close()
    summary, sections = merged_sections(cls)
    summary = PROTOCOL_SUMMARY.get(env_id, summary)
    if "preset" in spec.kwargs:  # the protocol ids: the published setup the preset applies
        from ..envs import presets

        setup = inspect.cleandoc(presets.__doc__).split("\n\n")[2]
        sections = {"Description": setup, **{k: v for k, v in sections.items() if k != "Description"}}
        sections = {name: sections[name] for name in SECTIONS if name in sections}
    mechanism, _, task = summary.partition(": ")
    return EnvFacts(env_id, str(spec.entry_point), int(spec.max_episode_steps), dt, tuple(obs_shape),
                    tuple(act_shape), *spaces, mechanism.strip(), task.strip().rstrip("."), _baselines(env_id),
                    dict(spec.kwargs), sections)  # fmt: skip


def registered_ids() -> list[str]:
    """Every id this package registers, in the registry's order, then the protocol ids and their training ids."""
    return [s.id for s in registry.SCENES] + [pid for pid, _, _, _ in PROTOCOL_IDS + TRAINING_IDS]


def environments_table(facts: list[EnvFacts], link: str = "docs/environments/{slug}.md") -> str:
    """The README's table of environments (Markdown), one row per id, each linking to its page."""
    rows = ["| id | mechanism | task | obs | act | steps (s) | model-based baseline |", "|---|---|---|---|---|---|---|"]
    for f in facts:
        seconds = f"{f.max_episode_steps * f.dt:g}"
        rows.append(f"| [`{f.id}`]({link.format(slug=f.slug)}) | {to_markdown(f.mechanism)} | {to_markdown(f.task)} "
                    f"| {', '.join(map(str, f.observation_shape))} | {', '.join(map(str, f.action_shape))} "
                    f"| {f.max_episode_steps} ({seconds}) | {', '.join(f.baselines)} |")  # fmt: skip
    return "\n".join(rows)


def env_page(f: EnvFacts, gif: str | None = None) -> str:
    """The documentation page of one id (MyST Markdown), its header then its docstring's sections."""
    preset = f.kwargs.get("preset")
    make = f'gym.make("{f.id}")'
    lines = [f"# {f.id.split('/', 1)[1]}", "", f"{to_markdown(f.mechanism)}: {to_markdown(f.task)}.", ""]
    if gif:
        lines += [f"![{f.id}]({gif})", ""]
    lines += ["| | |", "|---|---|",
              f"| Action Space | `{f.action_space}` |",
              f"| Observation Space | `{f.observation_space}` |",
              f"| Control step | {f.dt:g} s |",
              f"| Episode length | {f.max_episode_steps} steps ({f.max_episode_steps * f.dt:g} s) |",
              f"| Model-based baselines | {', '.join(f.baselines)} |",
              f"| Import | `import mbs_envs; {make}` |",
              f"| Class | `{f.entry_point.replace(':', '.')}` |", ""]  # fmt: skip
    if preset:
        lines += [f"The id is the class's task with the preset `{preset}` "
                  f"(`mbs_envs.envs.presets`) and {f.max_episode_steps} steps.", ""]  # fmt: skip
    for name, body in f.sections.items():
        lines += [f"## {name}", "", to_markdown(body), ""]
    return "\n".join(lines).rstrip() + "\n"
