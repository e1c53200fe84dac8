"""The package's shape (issue #12): no import cycles between modules, no private names across modules,
a shared-utility module that imports nothing of the package, and atomic writes that keep file modes."""

import ast
import os
import stat
from pathlib import Path

from jgrounding import io

ROOT = Path(__file__).resolve().parent.parent
PKG = ROOT / "jgrounding"


def _modules() -> dict[str, Path]:
    mods = {}
    for p in PKG.rglob("*.py"):
        name = ".".join(p.relative_to(ROOT).with_suffix("").parts)
        mods[name.removesuffix(".__init__")] = p
    return mods


def _imports(path: Path, mods) -> tuple[set[str], set[tuple[str, str]]]:
    """Modules of the package that ``path`` imports (anywhere, lazily too), and the package's private names it
    reaches (``from jgrounding.x import _y`` or ``x._y`` on a name bound to one of our modules)."""
    deps, private, ours = set(), set(), set()
    tree = ast.parse(path.read_text())
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("jgrounding"):
            ours.update(a.asname or a.name for a in node.names)
        elif isinstance(node, ast.Import):
            ours.update((a.asname or a.name).split(".")[0] for a in node.names if a.name.startswith("jgrounding"))
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("jgrounding"):
            for a in node.names:
                full = f"{node.module}.{a.name}"
                deps.add(full if full in mods else node.module)
                if a.name.startswith("_") and not a.name.startswith("__"):
                    private.add(full)
        elif isinstance(node, ast.Import):
            deps.update(a.name for a in node.names if a.name.startswith("jgrounding"))
        elif (
            isinstance(node, ast.Attribute)
            and node.attr.startswith("_")
            and not node.attr.startswith("__")
            and isinstance(node.value, ast.Name)
            and node.value.id in ours
        ):
            private.add(f"{node.value.id}.{node.attr}")
    return deps & set(mods), private


def _graph():
    mods = _modules()
    return {name: _imports(p, mods)[0] - {name} for name, p in mods.items()}


def test_no_import_cycles():
    graph = _graph()

    def related(a, b):  # a package and its own submodules may import each other (re-exports)
        return a.startswith(b + ".") or b.startswith(a + ".")

    cycles = []
    for start in graph:  # depth-first search for a path back to start through unrelated modules
        stack = [(start, (start,))]
        while stack:
            node, path = stack.pop()
            for nxt in graph[node]:
                if related(node, nxt):
                    continue
                if nxt == start:
                    cycles.append(path + (start,))
                elif nxt not in path and len(path) < 8:
                    stack.append((nxt, path + (nxt,)))
    assert not cycles, f"import cycles: {sorted(set(cycles))[:5]}"


def test_no_private_names_across_modules():
    mods = _modules()
    found = {(name, priv) for name, p in mods.items() for priv in _imports(p, mods)[1]}
    for d in ("tests", "experiments", "tools"):
        for p in (ROOT / d).rglob("*.py"):
            found |= {(str(p.relative_to(ROOT)), priv) for priv in _imports(p, mods)[1]}
    assert not found, f"private names used across modules: {sorted(found)}"


def test_io_imports_nothing_of_the_package():
    assert _graph()["jgrounding.io"] == set()


def test_write_atomic_keeps_the_file_mode(tmp_path):
    fresh = io.write_atomic(tmp_path / "new.csv", "a")
    umask = os.umask(0)
    os.umask(umask)
    assert stat.S_IMODE(fresh.stat().st_mode) == 0o666 & ~umask  # not mkstemp's private 0600
    target = tmp_path / "shared.csv"
    target.write_text("old")
    target.chmod(0o640)
    io.write_atomic(target, b"new")
    assert stat.S_IMODE(target.stat().st_mode) == 0o640 and target.read_bytes() == b"new"
    io.write_atomic(target, "x", mode=0o600)
    assert stat.S_IMODE(target.stat().st_mode) == 0o600
