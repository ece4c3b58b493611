"""The house rules of the source tree (docs/architecture.md), checked on every test run:
the import contracts of ``.importlinter`` (layers, a ROS-free core), no import cycle, no
private name used across modules, no import inside a function but of a deferred optional
dependency, no module over 400 lines and no function over 80 in the packages' sources."""
import ast
import os
import re
import subprocess

import networkx as nx
import pytest

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
#: the Python packages of the workspace: name -> folder holding the package folder
PACKAGES = {"patrolling_sim": os.path.join(ROOT, "src", "patrolling_sim", "src"),
            "spqrel_nav_lite": os.path.join(ROOT, "src", "spqrel_nav_lite", "src")}
#: the programs beside the packages (nodes, tools, scripts): sizes are checked there too
PROGRAM_DIRS = [os.path.join(ROOT, "src", p, d) for p in ("patrolling_sim", "spqrel_nav_lite")
                for d in ("nodes", "tools")
                if os.path.isdir(os.path.join(ROOT, "src", p, d))] + [os.path.join(ROOT, "scripts")]
#: dependencies that may be imported inside a function: heavy or optional ones that only one
#: feature needs (docs/architecture.md, "Deferred imports"); a dotted name covers its
#: submodules (the report layer: pandas and matplotlib, for a campaign's optional report)
DEFERRED = {"distributed", "dask", "cv2", "skimage", "pandas", "matplotlib", "tkinter",
            "rospy", "std_msgs", "scipy", "patrolling_sim.report"}
MAX_MODULE_LINES = 400
MAX_FUNCTION_LINES = 80
LINT_IMPORTS = os.path.join(ROOT, ".venv", "bin", "lint-imports")


def _modules():
    """(module name, path) of every module of the workspace's packages."""
    for pkg, base in PACKAGES.items():
        for d, _, files in os.walk(os.path.join(base, pkg)):
            for f in sorted(files):
                if f.endswith(".py"):
                    rel = os.path.relpath(os.path.join(d, f), base)[:-3].replace(os.sep, ".")
                    yield rel[:-len(".__init__")] if rel.endswith(".__init__") else rel, \
                        os.path.join(d, f)


MODULES = dict(_modules())


def _imports(path, module=None):
    """[(imported name, ImportFrom alias names or None, node, inside a function)] of a file;
    relative imports are resolved against ``module`` (the file's module name)."""
    tree = ast.parse(open(path, encoding="utf-8").read(), path)
    package = (module if path.endswith("__init__.py") else (module or "").rpartition(".")[0])
    out = []

    def visit(node, in_function):
        for child in ast.iter_child_nodes(node):
            inner = in_function or isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef))
            if isinstance(child, ast.Import):
                out.extend((a.name, None, child, in_function) for a in child.names)
            elif isinstance(child, ast.ImportFrom):
                name = child.module
                if child.level:
                    base = package.split(".")[:len(package.split(".")) - child.level + 1]
                    name = ".".join(base + ([child.module] if child.module else []))
                out.append((name, [a.name for a in child.names], child, in_function))
            visit(child, inner)
    visit(tree, False)
    return out


def _project_module(name):
    """The longest project module that ``name`` starts with, or None."""
    while name:
        if name in MODULES:
            return name
        name = name.rpartition(".")[0]
    return None


def test_import_contracts_hold():
    """lint-imports (import-linter, installed into .venv/ by scripts/setup.sh) keeps the
    contracts of .importlinter."""
    assert os.path.exists(LINT_IMPORTS), "import-linter missing: run `make setup`"
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(PACKAGES.values()))
    r = subprocess.run([LINT_IMPORTS, "--config", os.path.join(ROOT, ".importlinter")],
                       cwd=ROOT, env=env, capture_output=True, text=True)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-2000:]


def test_no_import_cycle():
    """No cycle in the graph of module imports, wherever in a module they stand."""
    g = nx.DiGraph()
    for mod, path in MODULES.items():
        g.add_node(mod)
        for name, names, _, _ in _imports(path, mod):
            targets = [name] if names is None else [f"{name}.{n}" for n in names] + [name]
            for t in targets:
                dep = _project_module(t)
                if dep and dep != mod and not mod.startswith(dep + "."):
                    g.add_edge(mod, dep)
    cycles = list(nx.simple_cycles(g))
    assert not cycles, "import cycles: " + "; ".join(" -> ".join(c) for c in cycles[:5])


def test_no_private_name_crosses_modules():
    """A name starting with '_' is used only in the module that defines it."""
    bad = []
    for mod, path in MODULES.items():
        imported = {}
        for name, names, node, _ in _imports(path, mod):
            if names is None:
                continue
            for n in names:
                if _project_module(name) and n.startswith("_") and not n.startswith("__"):
                    bad.append(f"{path}:{node.lineno}: imports {name}.{n}")
                if f"{name}.{n}" in MODULES:
                    imported[n] = f"{name}.{n}"
        tree = ast.parse(open(path, encoding="utf-8").read(), path)
        for node in ast.walk(tree):
            if (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name)
                    and node.value.id in imported and node.attr.startswith("_")
                    and not node.attr.startswith("__")):
                bad.append(f"{path}:{node.lineno}: uses {imported[node.value.id]}.{node.attr}")
    assert not bad, "\n".join(bad)


def test_imports_inside_functions_are_deferred_dependencies_only():
    """An import inside a function is of a dependency listed in DEFERRED (heavy or optional,
    needed by one feature), never of a project module or a cheap library."""
    bad = [f"{path}:{node.lineno}: {name}"
           for mod, path in MODULES.items()
           for name, _, node, inside in _imports(path, mod)
           if inside and not any(name == d or name.startswith(d + ".") for d in DEFERRED)]
    assert not bad, "imports inside functions:\n" + "\n".join(bad)


def _sources():
    for path in MODULES.values():
        yield path
    for d in PROGRAM_DIRS:
        for f in sorted(os.listdir(d)):
            p = os.path.join(d, f)
            if os.path.isfile(p) and (f.endswith(".py") or os.path.basename(d) == "nodes"):
                yield p


@pytest.mark.parametrize("limit", [MAX_MODULE_LINES])
def test_modules_are_short(limit):
    long = [f"{p}: {n} lines" for p in _sources()
            for n in [open(p, encoding="utf-8").read().count("\n")] if n > limit]
    assert not long, f"modules over {limit} lines:\n" + "\n".join(long)


@pytest.mark.parametrize("limit", [MAX_FUNCTION_LINES])
def test_functions_are_short(limit):
    long = []
    for p in _sources():
        for node in ast.walk(ast.parse(open(p, encoding="utf-8").read(), p)):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                n = node.end_lineno - node.lineno + 1
                if n > limit:
                    long.append(f"{p}:{node.lineno}: {node.name}, {n} lines")
    assert not long, f"functions over {limit} lines:\n" + "\n".join(long)


def test_the_checks_see_the_whole_tree():
    """The checks above walk every module (a guard against a walk that finds nothing)."""
    assert {"patrolling_sim.model.graph", "patrolling_sim.campaign.engine",
            "spqrel_nav_lite.planner"} <= set(MODULES)
    assert len(MODULES) > 80


def test_comments_state_contracts_not_history():
    """No dates, issue numbers or CI run ids in the code, its comments and docstrings (the
    reasons and measurements behind a choice go in the commit message or bench/notes/)."""
    history = re.compile(r"\b20\d\d-\d\d-\d\d\b|\b[Ii]ssue \d+\b|\bci\d+\b")
    folders = [os.path.join(ROOT, d) for d in ("src", "scripts", "bench", "tests")]
    found = []
    for folder in folders:
        for d, dirs, files in os.walk(folder):
            dirs[:] = [x for x in dirs if x not in ("notes", "data", "__pycache__")]
            for f in files:
                p = os.path.join(d, f)
                if not (f.endswith((".py", ".cpp", ".h", ".launch", ".test"))
                        or os.path.basename(d) == "nodes"):
                    continue
                for n, line in enumerate(open(p, encoding="utf-8"), 1):
                    if history.search(line):
                        found.append(f"{os.path.relpath(p, ROOT)}:{n}: {line.strip()[:90]}")
    assert not found, "\n".join(found)
