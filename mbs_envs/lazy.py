"""Names a package serves on first access (PEP 562), so importing it loads only what is used;
and the module paths of earlier versions, served from where the modules live now."""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from typing import Any


def lazy_exports(package: str, names: Mapping[str, str], namespace: dict[str, Any]) -> tuple[Callable, Callable]:
    """``(__getattr__, __dir__)`` for ``package`` serving ``names`` (name -> submodule) on first access.

    A served name is stored in ``namespace`` (the package's globals), so later
    look-ups are plain attribute reads.
    """

    def __getattr__(name: str) -> Any:
        if name in names:
            value = getattr(importlib.import_module(f".{names[name]}", package), name)
            namespace[name] = value
            return value
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    def __dir__() -> list[str]:
        return sorted(set(namespace) | set(names))

    return __getattr__, __dir__


class ModuleAliases:
    """A meta path finder serving old module paths (``mbs_envs.sb3``) from the new ones
    (``mbs_envs.envs.sb3``): ``import``, ``from ... import`` and unpickling keep working, and
    the old name is the very same module object (imported only when asked for)."""

    def __init__(self, aliases: Mapping[str, str]):
        self.aliases = dict(aliases)

    def find_spec(self, fullname: str, path: Any = None, target: Any = None):
        if fullname not in self.aliases:
            return None
        import importlib.util

        return importlib.util.spec_from_loader(fullname, self)

    def create_module(self, spec):
        module = importlib.import_module(self.aliases[spec.name])
        self._specs = {**getattr(self, "_specs", {}), spec.name: module.__spec__}
        return module

    def exec_module(self, module) -> None:
        """Nothing to run (the target module is executed); give it back its own ``__spec__``,
        which the import system replaced by the alias's."""
        module.__spec__ = self._specs[module.__spec__.name]
