"""Layers you can see: no import cycles among magbench's modules, and no in-function imports of magbench's
own modules (only lazy imports of heavy third-party packages), checked on the source with ``ast``."""
import ast
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
PACKAGES = {"magbench": REPO / "magbench", "magbench.simulate": REPO / "simulate",
            "magbench.calibrators": REPO / "calibrators", "magbench.benchmarks": REPO / "benchmarks"}


def modules() -> dict[str, Path]:
    out = {}
    for package, root in PACKAGES.items():
        for path in root.rglob("*.py"):
            rel = path.relative_to(root)
            if rel.parts[0] in ("suite", "templates"):
                continue
            parts = list(rel.with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            out[".".join([package, *parts])] = path
    return out


def _resolve(module: str, path: Path, node: ast.ImportFrom) -> str:
    if node.level == 0:
        return node.module or ""
    base = module.split(".") if path.name == "__init__.py" else module.split(".")[:-1]
    base = base[:len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def imports(module: str, path: Path) -> tuple[set[str], list[str]]:
    """(magbench modules imported at module level, in-function imports of magbench modules as 'line: name')."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    known = modules()
    top, inner = set(), []

    def targets(node) -> list[str]:
        if isinstance(node, ast.Import):
            return [a.name for a in node.names]
        name = _resolve(module, path, node)
        found = [f"{name}.{a.name}" for a in node.names if f"{name}.{a.name}" in known]
        return found or [name]

    def visit(node, depth):
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.Import, ast.ImportFrom)):
                for t in targets(child):
                    if t.startswith("magbench"):
                        if depth:
                            inner.append(f"{path.relative_to(REPO)}:{child.lineno}: {t}")
                        elif not _type_checking_only(child, tree):
                            top.add(t)
            deeper = depth + isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda))
            visit(child, deeper)

    visit(tree, 0)
    return {t for t in top if t in known}, inner


def _type_checking_only(node, tree) -> bool:
    return False


CORE_LAYERS = ("magbench", "simulate", "calibrators")
"""The library layers: no in-function import of magbench's own modules at all."""
APPLICATION_LAZY_IMPORTS = 8
"""``benchmarks/`` (the harness and the command line) loads the modules of a heavy command when the command
runs, so that ``magbench --help`` and one-off commands do not import pandas, matplotlib and SciPy; the
count may only go down (a ratchet), and every such import must be of a module that loads one of those
packages when imported (``test_lazy_imports_are_only_of_heavy_modules``)."""
HEAVY = ("pandas", "matplotlib", "scipy", "numba")
LAZY_FOR_A_CYCLE: set[str] = set()
"""In-function imports kept to break an import cycle (none: a cycle is mended by moving code, as the blind
check's runner moved out of the diagnosis package into ``benchmarks/blindrun.py``)."""


def test_no_in_function_imports_of_magbench_modules_in_the_library_layers():
    inner = []
    for module, path in modules().items():
        if path.relative_to(REPO).parts[0] in CORE_LAYERS:
            inner += imports(module, path)[1]
    assert not inner, "in-function imports of magbench's own modules:\n" + "\n".join(inner)


def test_the_application_layer_lazy_imports_only_shrink():
    inner = [i for m, p in modules().items() if p.relative_to(REPO).parts[0] == "benchmarks"
             for i in imports(m, p)[1]]
    assert len(inner) <= APPLICATION_LAZY_IMPORTS, "\n".join(inner)


def test_no_import_cycles():
    graph = {m: imports(m, p)[0] for m, p in modules().items()}
    # a package's __init__ re-exporting its modules is not a cycle through the package's modules
    state, stack, cycles = {}, [], []

    def dfs(m):
        state[m] = 1
        stack.append(m)
        for n in sorted(graph.get(m, ())):
            if n == m or (m.startswith(n + ".") and n in PACKAGES):
                continue
            if state.get(n) == 1:
                cycles.append(" -> ".join(stack[stack.index(n):] + [n]))
            elif not state.get(n):
                dfs(n)
        stack.pop()
        state[m] = 2

    for m in sorted(graph):
        if not state.get(m):
            dfs(m)
    assert not cycles, "import cycles:\n" + "\n".join(cycles)


@pytest.mark.parametrize("source,expected", [
    ("def f():\n    from magbench import paper\n", 1),
    ("import numpy\n\ndef f():\n    import scipy\n", 0),
])
def test_negative_control_the_scan_finds_an_in_function_import(tmp_path, source, expected):
    path = REPO / "magbench" / "_layers_probe.py"
    path.write_text(source)
    try:
        assert len(imports("magbench._layers_probe", path)[1]) == expected
    finally:
        path.unlink()


def _loads_heavy(module: str, known: dict[str, Path], seen: set[str]) -> bool:
    """Whether importing ``module`` loads a HEAVY package at module level, directly or through the magbench
    modules it imports at module level."""
    if module in seen or module not in known:
        return False
    seen.add(module)
    tree = ast.parse(known[module].read_text(encoding="utf-8"))
    for node in tree.body:
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0:
            names = [node.module or ""]
        else:
            continue
        if any(n.split(".")[0] in HEAVY for n in names):
            return True
    top, _ = imports(module, known[module])
    return any(_loads_heavy(m, known, seen) for m in top)


def test_lazy_imports_are_only_of_heavy_modules():
    known = modules()
    light = []
    for module, path in known.items():
        if path.relative_to(REPO).parts[0] != "benchmarks":
            continue
        for line in imports(module, path)[1]:
            where, target = line.rsplit(": ", 1)
            key = f"{where.rsplit(':', 1)[0]}: {target}"
            if key not in LAZY_FOR_A_CYCLE and not _loads_heavy(target, known, set()):
                light.append(line)
    assert not light, "lazy imports of modules that load no heavy package (import them at module level):\n" + \
        "\n".join(light)
