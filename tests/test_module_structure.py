"""Module structure of `leonav_runtime/` and `hardware/`, read with `ast` (stdlib only).

- no module is longer than MAX_LINES (small modules, one job each);
- no import cycles between modules, counting imports inside functions too (a late import
  hides a cycle at load time but not in the design);
- the device layer does not reach up: `hardware/` imports nothing from `leonav_runtime`
  except the generated constants layer `leonav_runtime.gen`.
"""
from __future__ import annotations

import ast
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
PACKAGES = ("leonav_runtime", "hardware")
INSTALLED_AS = {"hardware": "leonav.hardware"}   # repository folder -> import name (setup.py)
MAX_LINES = 400
# Modules over the limit that belong to other work in progress; they may not grow.
OVER_LIMIT: dict[str, int] = {}


def _modules() -> dict[str, Path]:
    mods = {}
    for pkg in PACKAGES:
        for path in sorted((REPO / pkg).rglob("*.py")):
            parts = list(path.relative_to(REPO).with_suffix("").parts)
            parts[0] = INSTALLED_AS.get(parts[0], parts[0])
            if parts[-1] == "__init__":
                parts.pop()
            mods[".".join(parts)] = path
    return mods


def _imports(name: str, path: Path, mods: dict[str, Path]) -> set[str]:
    """Modules of `mods` that module `name` imports anywhere in its body."""

    def known(dotted: str) -> str | None:
        while dotted and dotted not in mods:
            dotted = dotted.rpartition(".")[0]
        return dotted or None

    out = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            targets = [known(a.name) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
                base = base[:len(base) - node.level + 1]
                module = ".".join(base + ([node.module] if node.module else []))
            else:
                module = node.module or ""
            targets = [f"{module}.{a.name}" if f"{module}.{a.name}" in mods else known(module) for a in node.names]
        else:
            continue
        out.update(t for t in targets if t and t != name)
    return out


def _graph() -> dict[str, set[str]]:
    mods = _modules()
    return {name: _imports(name, path, mods) for name, path in mods.items()}


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan, iterative)."""
    index, low, on_stack, stack, out = {}, {}, set(), [], []
    counter = 0
    for root in graph:
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = counter
                    counter += 1
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph[child]))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                comp = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    comp.append(member)
                    if member == node:
                        break
                if len(comp) > 1:
                    out.append(sorted(comp))
    return out


def test_no_module_is_longer_than_the_limit():
    too_long = {}
    for path in _modules().values():
        rel = path.relative_to(REPO).as_posix()
        n = len(path.read_text().splitlines())
        if n > OVER_LIMIT.get(rel, MAX_LINES):
            too_long[rel] = n
    assert not too_long, f"modules over {MAX_LINES} lines (split them): {too_long}"


def test_no_import_cycles():
    assert _cycles(_graph()) == []


def test_cycle_finder_finds_a_cycle():
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def test_hardware_does_not_import_the_runtime():
    reach_up = {name: sorted(t for t in targets if t.startswith("leonav_runtime") and
                             not t.startswith("leonav_runtime.gen"))
                for name, targets in _graph().items() if name.startswith("leonav.hardware")}
    assert {k: v for k, v in reach_up.items() if v} == {}
