"""The layering of the package (README, "Architecture"), checked on the source by its AST.

    apps      -> research, viz, io, geometry, method
    research  -> viz, io, geometry, method
    viz       -> geometry, method
    io        -> geometry, method
    geometry  -> (nothing)
    method    -> (nothing)

Every layer may use ``upsr.errors``, ``upsr._lazy``, ``upsr._numba`` and ``upsr._atomic``;
nothing imports ``upsr.apps`` (``upsr.__main__``, ``python -m upsr``, belongs to it). Imports
inside functions count as much as those at the top.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src" / "upsr"
COMMON = {"errors", "_lazy", "_numba", "_atomic"}
ALLOWED = {
    "method": {"method"},
    "geometry": {"geometry"},
    "io": {"io", "geometry", "method"},
    "viz": {"viz", "geometry", "method"},
    "research": {"research", "viz", "io", "geometry", "method"},
    "apps": {"apps", "research", "viz", "io", "geometry", "method"},
}


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(SRC.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _imports(path: Path) -> list[tuple[str, bool]]:
    """(imported upsr module, at module level) for every import statement of ``path``."""
    name = _module_name(path)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    tree = ast.parse(path.read_text(), str(path))
    top = {id(n) for n in tree.body}
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            mods = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            mods = [mod] + [f"{mod}.{a.name}" for a in node.names]
        else:
            continue
        found += [(m, id(node) in top) for m in mods if m == "upsr" or m.startswith("upsr.")]
    return found


def _layer(module: str) -> str | None:
    parts = module.split(".")
    if parts[1:2] == ["__main__"]:
        return "apps"  # (``python -m upsr``: the command line, as the ``upsr`` script)
    return parts[1] if len(parts) > 1 else None


def _sources() -> list[Path]:
    return sorted(SRC.rglob("*.py"))


def test_layers_import_only_what_they_may() -> None:
    broken = []
    for path in _sources():
        me = _layer(_module_name(path))
        if me is None or me in COMMON:
            allowed = COMMON | (
                {"method", "geometry", "io", "viz", "research"} if me is None else set()
            )
        else:
            allowed = ALLOWED[me] | COMMON
        for mod, _ in _imports(path):
            other = _layer(mod)
            if other not in ALLOWED and other not in COMMON:  # "from upsr import X", X a name
                continue
            if other not in allowed and (me, other) != (None, "apps"):
                broken.append(f"{_module_name(path)} imports {mod}")
    assert not broken, "\n".join(broken)


def test_nothing_imports_apps() -> None:
    users = [
        f"{_module_name(p)} imports {m}"
        for p in _sources()
        if _layer(_module_name(p)) != "apps"
        for m, _ in _imports(p)
        if _layer(m) == "apps"
    ]
    assert not users, "\n".join(users)


def test_no_import_cycle() -> None:
    """Module-level imports between upsr modules form no cycle."""
    modules = {_module_name(p): p for p in _sources()}
    graph: dict[str, set[str]] = {}
    for name, path in modules.items():
        graph[name] = {m for m, top in _imports(path) if top and m in modules and m != name}
    # a package's __init__ importing its own submodules lazily is not an edge; eager ones are
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(node: str) -> None:
        state[node] = 1
        stack.append(node)
        for nxt in graph[node]:
            if state.get(nxt) == 1:
                cycle = [*stack[stack.index(nxt) :], nxt]
                pytest.fail("import cycle: " + " -> ".join(cycle))
            if nxt not in state:
                visit(nxt)
        stack.pop()
        state[node] = 2

    for node in sorted(graph):
        if node not in state:
            visit(node)


@pytest.mark.parametrize(
    ("code", "forbidden"),
    [
        ("import upsr", ("upsr.research", "upsr.io.video", "upsr.method.windowed", "numba")),
        ("import upsr.io", ("upsr.research", "upsr.method.windowed")),
        ("import upsr.apps.cli.main", ("upsr.research", "upsr.method.windowed", "numba")),
    ],
)
def test_imports_stay_lazy(code: str, forbidden: tuple[str, ...]) -> None:
    """What a cheap import loads: never the research code or the compiled method."""
    probe = f"{code}; import sys; print('\\n'.join(sys.modules))"
    loaded = set(
        subprocess.run(
            [sys.executable, "-c", probe], capture_output=True, text=True, check=True
        ).stdout.split()
    )
    assert not loaded & set(forbidden), loaded & set(forbidden)


def test_module_and_function_sizes() -> None:
    """No module over 700 lines; no function over 120 lines except compiled kernels."""
    too_long = []
    for path in _sources():
        text = path.read_text()
        if text.count("\n") > 700:
            too_long.append(f"{_module_name(path)}: {text.count(chr(10))} lines")
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                decorators = [ast.unparse(d) for d in node.decorator_list]
                if any("njit" in d or "jit" in d for d in decorators):
                    continue
                n = node.end_lineno - node.lineno + 1
                if n > 120:
                    too_long.append(f"{_module_name(path)}.{node.name}: {n} lines")
    assert not too_long, "\n".join(too_long)
