"""Imports run one way: dynamics <- models <- envs <- controllers <- studies <- scripts, at module and function
level, with no cycle among the modules (an import under ``if TYPE_CHECKING:`` is an annotation, not an import)."""

import ast
import pathlib

ROOT = pathlib.Path(__file__).resolve().parents[1]
#: each package's layer; ``validation`` and ``lazy`` are helpers every layer may use
LAYERS = {"mbs_envs.validation": -1, "mbs_envs.lazy": -1, "mbs_envs.dynamics": 0, "mbs_envs.simulate": 0,
          "mbs_envs.models": 1, "mbs_envs.envs": 2, "mbs_envs": 2, "mbs_envs.controllers": 3, "mbs_envs.studies": 4,
          "scripts": 5}  # fmt: skip


def module_name(path: pathlib.Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[0] == "controllers":  # installed as mbs_envs.controllers
        parts = ["mbs_envs", *parts]
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def layer(module: str) -> int:
    key = max((k for k in LAYERS if module == k or module.startswith(k + ".")), key=len)
    return LAYERS[key]


def import_graph() -> dict[str, set[str]]:
    """Module -> the modules of this project it imports (anywhere in the file but under ``TYPE_CHECKING``)."""
    paths = [p for d in ("mbs_envs", "controllers", "scripts") for p in (ROOT / d).rglob("*.py")]
    modules = {module_name(p): p for p in paths}
    graph = {}
    for name, path in modules.items():
        tree = ast.parse(path.read_text())
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        skip = {id(n) for node in ast.walk(tree) if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.dump(node.test)
                for b in node.body for n in ast.walk(b)}  # fmt: skip
        targets = set()
        for node in ast.walk(tree):
            if id(node) in skip:
                continue
            if isinstance(node, ast.Import):
                targets |= {a.name for a in node.names}
            elif isinstance(node, ast.ImportFrom):
                base = package.split(".")[: len(package.split(".")) - node.level + 1] if node.level else []
                source = ".".join(base + ([node.module] if node.module else []))
                subs = {f"{source}.{a.name}" for a in node.names} & set(modules)
                targets |= subs | ({source} if len(subs) < len(node.names) else set())
        graph[name] = {t for t in targets if t in modules and t != name and t != "mbs_envs"}
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in graph:
        if v not in index:
            visit(v)
    return out


def test_no_module_imports_a_layer_above_its_own():
    graph = import_graph()
    upward = sorted((a, b) for a, targets in graph.items() for b in targets if layer(b) > layer(a))
    assert len(graph) > 100 and sum(map(len, graph.values())) > 300  # the walk sees the project
    assert upward == []


def test_no_import_cycle():
    assert cycles(import_graph()) == []


def test_the_checks_can_fail():
    """An upward edge and a cycle put into a copy of the graph are found."""
    graph = {k: set(v) for k, v in import_graph().items()}
    graph["mbs_envs.dynamics.simulate"].add("mbs_envs.studies.comparison")
    assert any(layer(b) > layer(a) for a, t in graph.items() for b in t)
    graph["mbs_envs.studies.comparison"].add("mbs_envs.dynamics.simulate")
    graph["mbs_envs.dynamics.simulate"].add("mbs_envs.studies.comparison")
    assert cycles(graph)
