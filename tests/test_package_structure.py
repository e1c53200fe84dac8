"""The package's shape (issues #12, #22; named apart from tests/semantics/test_structure.py, since pytest's
default import mode needs unique basenames): no import cycles between modules, no private names across modules,
a shared-utility module that imports nothing of the package, atomic writes that keep file modes, layers that
import downward only, and no name (an import, a ``python -m`` command, a dotted path in the docs or a docstring)
that points at a module or attribute that does not exist."""

import ast
import os
import re
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


# --- Names that must exist (issue #22: `experiments/ablation.py --folds 4` imported the moved
# `jgrounding.export`, and the old check skipped imports of modules it did not know) ----------------------

OURS = ("jgrounding", "experiments", "tools")


def _all_modules() -> dict[str, Path]:
    mods = {}
    for d in OURS:
        for p in (ROOT / d).rglob("*.py"):
            mods[".".join(p.relative_to(ROOT).with_suffix("").parts).removesuffix(".__init__")] = p
    return mods


def _lazy(tree) -> dict[str, tuple[str, str | None]]:
    """A package's ``_LAZY = {public name: (module, attribute)}`` (resolved by its ``__getattr__``)."""
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(isinstance(t, ast.Name) and t.id == "_LAZY" for t in node.targets):
            return ast.literal_eval(node.value)
    return {}


_DEFINED: dict[Path, set[str]] = {}


def _defined(path: Path) -> set[str]:
    """Names a module defines at import time (functions, classes, assignments, imports, also inside top-level
    ``if``/``try`` blocks), ``Class.member`` for class bodies, and its ``_LAZY`` public names."""
    if path not in _DEFINED:
        tree = ast.parse(path.read_text())
        out = set(_lazy(tree))

        def visit(body, prefix=""):
            for n in body:
                if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                    out.add(prefix + n.name)
                    if isinstance(n, ast.ClassDef) and not prefix:
                        visit(n.body, n.name + ".")
                elif isinstance(n, (ast.Assign, ast.AnnAssign, ast.AugAssign)):
                    for t in n.targets if isinstance(n, ast.Assign) else [n.target]:
                        out.update(prefix + x.id for x in ast.walk(t) if isinstance(x, ast.Name))
                elif isinstance(n, (ast.Import, ast.ImportFrom)) and not prefix:
                    out.update((a.asname or a.name).split(".")[0] for a in n.names)
                elif isinstance(n, (ast.If, ast.Try, ast.With, ast.For)):
                    visit(n.body + getattr(n, "orelse", []) + getattr(n, "finalbody", []), prefix)
                    for h in getattr(n, "handlers", []):
                        visit(h.body, prefix)

        visit(tree.body)
        _DEFINED[path] = out
    return _DEFINED[path]


def _resolves(ref: str, mods) -> bool:
    """``a.b.c``: a module, or a module's attribute (``module.name`` or ``module.Class.member``)."""
    parts = ref.split(".")
    for i in range(len(parts), 0, -1):
        mod = ".".join(parts[:i])
        if mod in mods:
            rest = parts[i:]
            return not rest or ".".join(rest[:2]) in _defined(mods[mod]) or rest[0] in _defined(mods[mod])
    return False


def _import_targets(path: Path, mods):
    """(line, dotted target) for every import of our packages in ``path``, lazy ones inside functions too:
    ``import a.b`` -> ``a.b``; ``from a import b`` -> ``a.b`` (module or attribute);
    ``importlib.import_module("a.b")`` -> ``a.b``."""
    tree = ast.parse(path.read_text())
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            if node.module.split(".")[0] in OURS:
                for a in node.names:
                    yield node.lineno, node.module if a.name == "*" else f"{node.module}.{a.name}"
        elif isinstance(node, ast.Import):
            for a in node.names:
                if a.name.split(".")[0] in OURS:
                    yield node.lineno, a.name
        elif (
            isinstance(node, ast.Call)
            and isinstance(node.func, ast.Attribute)
            and node.func.attr == "import_module"
            and node.args
            and isinstance(node.args[0], ast.Constant)
            and str(node.args[0].value).split(".")[0] in OURS
        ):
            yield node.lineno, node.args[0].value


def _python_files():
    yield from _all_modules().values()
    yield from (ROOT / "tests").rglob("*.py")


def test_every_import_names_a_module_or_attribute_that_exists():
    mods = _all_modules()
    missing = [
        f"{p.relative_to(ROOT)}:{line}: {target}"
        for p in _python_files()
        for line, target in _import_targets(p, mods)
        if not _resolves(target, mods)
    ]
    root_lazy = _lazy(ast.parse((PKG / "__init__.py").read_text()))
    missing += [
        f"jgrounding/__init__.py _LAZY[{name!r}]: {module}.{attr}"
        for name, (module, attr) in root_lazy.items()
        if not _resolves(module if attr is None else f"{module}.{attr}", mods)
    ]
    assert not missing, "imports of modules or names that do not exist:\n" + "\n".join(missing)


def _text_files():
    yield ROOT / "README.md"
    yield ROOT / "Makefile"
    yield from sorted((ROOT / "docs").rglob("*.md"))
    yield from _python_files()


def test_short_cross_references_in_docstrings_resolve():
    """Sphinx-style references that name a module by its last part (:func:`methods.generate`,
    :mod:`sampling`) resolve, where that short name is one module of ours: after a move, a docstring that
    still says :func:`methods.restore` is caught (issue #22: three did, and the dotted-name guard above only
    reads full ``jgrounding.x.y`` names)."""
    mods = _all_modules()
    short: dict[str, list[str]] = {}
    for name in mods:
        short.setdefault(name.rsplit(".", 1)[-1], []).append(name)
    role = re.compile(r":(?:func|meth|class|data|attr|mod):`~?([A-Za-z_][\w.]*)`")
    bad = []
    for f in _text_files():
        if f == Path(__file__).resolve():
            continue  # its docstring names the moved functions on purpose
        for i, line in enumerate(f.read_text().splitlines(), 1):
            for m in role.finditer(line):
                ref = m.group(1)
                head, _, rest = ref.partition(".")
                if ref.startswith(("jgrounding.", "experiments.", "tools.")) or len(short.get(head, [])) != 1:
                    continue  # full names: the guard above; unknown or ambiguous short names: not checked
                if not _resolves(f"{short[head][0]}.{rest}".rstrip("."), mods):
                    bad.append(f"{f.relative_to(ROOT)}:{i}: {ref}")
    assert not bad, "cross-references to names that do not exist (moved or renamed?):\n" + "\n".join(bad)


def test_module_commands_in_docs_and_code_exist():
    """Every ``python -m <module>`` (``$(PY) -m`` in the Makefile) in the README, docs, Makefile, code and tests names a runnable module."""
    mods = _all_modules()
    bad = []
    for f in _text_files():
        for i, line in enumerate(f.read_text().splitlines(), 1):
            for m in re.finditer(r"(?:python3?|\$\(PY\)) -m ((?:jgrounding|experiments|tools)[\w.]*)", line):
                name = m.group(1).rstrip(".")
                if name not in mods and f"{name}.__main__" not in mods:
                    bad.append(f"{f.relative_to(ROOT)}:{i}: python -m {name}")
    assert not bad, "commands that name a module that does not exist:\n" + "\n".join(bad)


def test_dotted_names_in_docs_and_docstrings_resolve():
    """``jgrounding.x.y`` / ``experiments.x`` / ``tools.x`` written anywhere (README, docs, docstrings, comments,
    logger names shown in docs) names a module or an attribute of one. Patterns such as
    ``experiments.bench_<name>`` are not names."""
    mods = _all_modules()
    pattern = re.compile(r"(?<![\w/.-])((?:jgrounding|experiments|tools)(?:\.[A-Za-z_]\w*)+)(?![\w<*{])")
    bad = []
    for f in _text_files():
        if f == Path(__file__).resolve():
            continue  # its examples name modules that do not exist on purpose
        for i, line in enumerate(f.read_text().splitlines(), 1):
            for m in pattern.finditer(line):
                ref = m.group(1)
                if re.search(r"\.(py|md|npz|json|txt|csv|png|gif|xml|html)$", ref) or ref.endswith("_"):
                    continue  # a file name, or a name pattern
                if not _resolves(ref, mods):
                    bad.append(f"{f.relative_to(ROOT)}:{i}: {ref}")
    assert not bad, "dotted names that point nowhere (moved or renamed?):\n" + "\n".join(bad)


def test_source_paths_named_in_docs_and_code_exist():
    """``jgrounding/…/x.py``, ``experiments/x.py``, ``tools/x.py`` and ``tests/…/x.py`` written in the README,
    docs, code or tests name files that exist (tests moved into stage folders, modules into packages)."""
    pattern = re.compile(r"(?<![\w./-])((?:jgrounding|experiments|tools|tests)/[\w/.-]*\.py)\b")
    bad = [
        f"{f.relative_to(ROOT)}:{i}: {m.group(1)}"
        for f in _text_files()
        if f != Path(__file__).resolve()
        for i, line in enumerate(f.read_text().splitlines(), 1)
        for m in pattern.finditer(line)
        if not (ROOT / m.group(1)).exists()
    ]
    assert not bad, "paths of files that do not exist (moved?):\n" + "\n".join(bad)


# --- Layers run one way (issue #22) --------------------------------------------------------------------------
# base (the package root, its shared utilities, sim, actuation, semantics, library) -> generators -> training
# -> policy (jg.sample: restores checkpoints, so above training) -> evaluation -> apps / serving / serve /
# client / experiments / tools. A module imports from its own layer or below;
# lazy imports inside functions count. ``from jgrounding import sample`` and ``jg.sample`` count as what the
# root's lazy table resolves them to.

LAYERS = {
    "jgrounding": 0,  # the root package: its eager imports are base modules; its lazy names are the facade
    "jgrounding.io": 0,
    "jgrounding.vocabulary": 0,
    "jgrounding.config": 0,
    "jgrounding.safety": 0,
    "jgrounding.sim": 0,
    "jgrounding.actuation": 0,
    "jgrounding.semantics": 0,
    "jgrounding.library": 0,
    "jgrounding.generators": 1,
    "jgrounding.training": 2,
    "jgrounding.policy": 3,
    "jgrounding.evaluation": 4,
    "jgrounding.apps": 5,
    "jgrounding.serving": 5,  # the policy server; the client shares its wire codec (jgrounding.serving.wire)
    "jgrounding.serve": 5,
    "jgrounding.study": 5,  # the user study (docs/study.md): its server is on jgrounding.serving
    "jgrounding.client": 5,
    "jgrounding.__main__": 5,
    "experiments": 5,
    "tools": 5,
}
LAYER_NAMES = ("base", "generators", "training", "policy", "evaluation", "apps/serving/experiments/tools")

# Known upward imports: (importer, imported module) -> why it is there. Issue #22's refactor removed the last
# seven (a trained model that owns its sampling, training and restore in training/, batch generation in
# evaluation/, screening in sim/, the public sampler in policy/); keep it empty. A NEW upward import fails the
# test; so does an entry that no longer occurs.
KNOWN_UPWARD: dict = {}


def _layer(module: str) -> int:
    parts = module.split(".")
    for i in range(len(parts), 0, -1):
        if ".".join(parts[:i]) in LAYERS:
            return LAYERS[".".join(parts[:i])]
    raise AssertionError(f"{module} has no layer: add its package to LAYERS in tests/test_package_structure.py")


def _dependencies(path: Path, mods) -> set[str]:
    """Modules ``path`` imports (lazily too); a name of the root package counts as the module it resolves to."""
    root = _lazy(ast.parse((PKG / "__init__.py").read_text()))
    deps = set()
    for _, target in _import_targets(path, mods):
        parent, _, name = target.rpartition(".")
        if parent == "jgrounding" and name in root:
            deps.add(root[name][0])
        else:
            deps.add(target if target in mods else parent)
    tree = ast.parse(path.read_text())
    aliases = {
        a.asname or a.name
        for n in ast.walk(tree)
        if isinstance(n, ast.Import)
        for a in n.names
        if a.name == "jgrounding"
    }
    for n in ast.walk(tree):  # jg.sample with jg bound to the root package
        if isinstance(n, ast.Attribute) and isinstance(n.value, ast.Name) and n.value.id in aliases:
            if n.attr in root:
                deps.add(root[n.attr][0])
    return {d for d in deps if d in mods}


def _upward() -> dict[tuple[str, str], int]:
    mods = _all_modules()
    found = {}
    for name, path in mods.items():
        if name == "jgrounding":
            continue  # the facade's lazy names point up on purpose; its eager imports are checked below
        for dep in _dependencies(path, mods):
            if _layer(dep) > _layer(name):
                found[(name, dep)] = _layer(dep)
    return found


def test_layers_import_downward_only():
    found = _upward()
    new = sorted(set(found) - set(KNOWN_UPWARD))
    assert not new, (
        "imports that run upward ("
        + " -> ".join(LAYER_NAMES)
        + "):\n"
        + "\n".join(f"{a} ({LAYER_NAMES[_layer(a)]}) imports {b} ({LAYER_NAMES[_layer(b)]})" for a, b in new)
    )
    gone = sorted(set(KNOWN_UPWARD) - set(found))
    assert not gone, f"fixed upward imports: remove them from KNOWN_UPWARD in tests/test_package_structure.py: {gone}"


def test_the_root_package_imports_only_base_modules_eagerly():
    mods = _all_modules()
    tree = ast.parse((PKG / "__init__.py").read_text())
    eager = {
        f"{n.module}.{a.name}" if f"{n.module}.{a.name}" in mods else n.module
        for n in tree.body
        if isinstance(n, ast.ImportFrom) and n.module and n.module.startswith("jgrounding")
        for a in n.names
    }
    assert eager and all(_layer(m) == 0 for m in eager), eager


def test_the_layer_check_sees_lazy_and_facade_imports(tmp_path):
    mods = _all_modules()
    src = tmp_path / "m.py"
    src.write_text(
        "import jgrounding as jg\n"
        "def f():\n"
        "    from jgrounding.evaluation import metrics\n"
        "    return jg.sample\n"
        "from jgrounding import ground\n"
    )
    assert _dependencies(src, mods) == {
        "jgrounding",
        "jgrounding.evaluation.metrics",
        "jgrounding.policy.sampling",
        "jgrounding.semantics",
    }
    src.write_text("from jgrounding import export\nimport jgrounding.trunk_model\n")
    assert [t for _, t in _import_targets(src, mods) if not _resolves(t, mods)] == [
        "jgrounding.export",
        "jgrounding.trunk_model",
    ]


def test_jg_sim_is_the_trunk_simulation_and_jg_trunk_its_alias():
    import jgrounding as jg
    from jgrounding import sim

    assert jg.sim is sim and jg.trunk is sim  # one package, one documented name (jg.sim), one older alias
