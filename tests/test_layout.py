"""The layout rules of the project (STYLE.md, "A module does one thing and the arrows point down")."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("base", "cosim", "ga", "sim_world", "hdl", "peers", "formal", "benchmarks")
BACKENDS = {"cosim.boards.amaranth_backend", "cosim.boards.cocotb_backend", "cosim.launch.cocotb_test", "cosim.launch.cocotb_sim"}


def _modules() -> dict[str, Path]:
    found = {}
    for package in PACKAGES:
        for path in (ROOT / package).rglob("*.py"):
            name = ".".join(path.relative_to(ROOT).with_suffix("").parts)
            found[name.removesuffix(".__init__")] = path
    return found


def _imports(path: Path, known) -> set[str]:
    """The project modules ``path`` imports anywhere (functions included), except under
    ``if __name__ == "__main__":`` (the script entry point is not the module)."""
    tree = ast.parse(path.read_text())
    skip = {id(n) for node in ast.walk(tree) if isinstance(node, ast.If)
            and ast.unparse(node.test).replace("'", '"') == '__name__ == "__main__"' for n in ast.walk(node)}
    out = set()
    for node in ast.walk(tree):
        if id(node) in skip:
            continue
        if isinstance(node, ast.Import):
            out |= {a.name for a in node.names if a.name in known}
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            out |= {node.module} & set(known)
            out |= {f"{node.module}.{a.name}" for a in node.names} & set(known)
    return out


def test_no_import_cycle():
    modules = _modules()
    graph = {m: _imports(p, modules) - {m} for m, p in modules.items()}

    def reaches(start, goal, seen):
        return any(n == goal or (n not in seen and not seen.add(n) and reaches(n, goal, seen)) for n in graph[start])

    cycles = sorted(m for m in graph if reaches(m, m, set()))
    assert cycles == []


def test_experiment_loops_import_no_backend_and_backends_no_loop():
    modules = _modules()
    loops = {"cosim.online.run", "cosim.cli.online", "cosim.offline.run", "cosim.online.failures", "cosim.online.download",
             "cosim.online.report", "cosim.online.config"}
    for loop in loops:
        assert not _imports(modules[loop], modules) & BACKENDS, loop
    for backend in ("cosim.boards.amaranth_backend", "cosim.boards.cocotb_backend"):
        assert not _imports(modules[backend], modules) & loops, backend


def test_no_package_file_over_500_lines():
    sizes = {str(p.relative_to(ROOT)): len(p.read_text().splitlines()) for p in _modules().values()}
    assert max(sizes.values()) <= 500, sorted(sizes.items(), key=lambda kv: -kv[1])[:5]
    assert sizes["cosim/online/run.py"] <= 400  # the lifetime loop reads like SPEC section 7


# The floors, bottom to top: a module imports only from its own floor's package or the floors
# below it (cosim's package docstring). benchmarks sits on top.
FLOORS = {"base": 0, "ga": 1, "sim_world": 2, "hdl": 2, "peers": 3, "formal": 3, "cosim.paper": 3,
          "cosim.boards": 4, "cosim.link": 5, "cosim.online": 5, "cosim.offline": 5,
          "cosim.compare": 6, "cosim.launch": 6, "cosim.report": 6, "cosim.cli": 7, "benchmarks": 8}


def _floor(module: str) -> str:
    parts = module.split(".")
    return ".".join(parts[:2]) if parts[0] == "cosim" and len(parts) > 1 else parts[0]


def test_imports_point_down():
    modules = _modules()
    upward = []
    for name, path in modules.items():
        mine = _floor(name)
        if mine not in FLOORS:
            continue
        for other in _imports(path, modules):
            theirs = _floor(other)
            if theirs in FLOORS and theirs != mine and FLOORS[theirs] >= FLOORS[mine]:
                upward.append(f"{name} -> {other}")
    assert upward == []


def test_only_cocotb_imports_a_test_module():
    modules = _modules()
    tests = {"cosim.launch.cocotb_test", "cosim.launch.uart_test"}
    assert not [m for m, p in modules.items() if _imports(p, modules) & tests]
