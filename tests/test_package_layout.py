"""The package's layout, checked from its source text (no module is imported).

The documented layout: imports go one way, from the foundation up to the CLI.

====================  =====================================================
area                  may import (of gyrodenoise)
====================  =====================================================
errors, units         nothing
_extras               errors
console               errors
core                  core, errors
analysis, io,         core, errors, units, console, data, analysis, io,
simulator, denoiser   simulator, denoiser
modelgap, fmu,        anything but cli
flightlog
cli                   anything
====================  =====================================================

Only ``gyrodenoise.cli`` (and a ``gyrodenoise/__main__.py`` entry point, if there is one)
imports ``gyrodenoise.cli``.

``LAYOUT`` below is that table; :func:`test_layers_go_one_way` holds every module to it.
Besides: no import cycle among the package's modules (module-level and function-level
imports alike; imports under ``if TYPE_CHECKING:`` do not run and are not counted), the
package reads nothing outside itself, and names no issue numbers.
"""

from __future__ import annotations

import ast
import importlib.util
import os
import re
from pathlib import Path


PACKAGE = "gyrodenoise"
PACKAGE_DIR = Path(importlib.util.find_spec(PACKAGE).submodule_search_locations[0]).resolve()
REPO_DIR = PACKAGE_DIR.parent      # the checkout (the test reads its tests, benchmarks and docs)

_LOWER = ("core", "errors", "units", "_extras", "console", "data", "analysis", "io", "simulator", "denoiser")
_ALL_BUT_CLI = _LOWER + ("modelgap", "fmu", "flightlog", "")
# area (relative to gyrodenoise; "" is the top-level package facade) -> the areas it may import.
# A module's area is the longest key that is its name or a parent of it.
LAYOUT = {
    "errors": (),
    "units": (),
    "_extras": ("errors",),
    "console": ("errors",),
    "core": ("core", "errors"),
    "analysis": _LOWER,
    "io": _LOWER,
    "simulator": _LOWER,
    "denoiser": _LOWER,
    "modelgap": _ALL_BUT_CLI,
    "fmu": _ALL_BUT_CLI,
    "flightlog": _ALL_BUT_CLI,
    "cli": _ALL_BUT_CLI + ("cli",),
}
CLI_ENTRY_POINTS = {f"{PACKAGE}.__main__"}     # ``python -m gyrodenoise``: runs the CLI


# ------------------------------------------------------------------ the import graph
def _module_name(path):
    rel = path.relative_to(PACKAGE_DIR).with_suffix("")
    parts = [PACKAGE, *rel.parts]
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _package_modules():
    """{module name: path} of every Python module under the package, and the names of
    its compiled extensions (``_gdcore.cpython-311-...so`` -> ``..._gdcore``)."""
    modules = {}
    for path in sorted(PACKAGE_DIR.rglob("*.py")):
        if "__pycache__" not in path.parts:
            modules[_module_name(path)] = path
    for suffix in ("*.so", "*.pyd"):
        for path in PACKAGE_DIR.rglob(suffix):
            rel = path.relative_to(PACKAGE_DIR)
            name = ".".join([PACKAGE, *rel.parts[:-1], path.name.split(".")[0]])
            modules.setdefault(name, None)
    return modules


def _is_type_checking(test):
    return ((isinstance(test, ast.Name) and test.id == "TYPE_CHECKING")
            or (isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"))


def _import_nodes(tree):
    """Every Import / ImportFrom node, at any depth, except under ``if TYPE_CHECKING:``."""
    stack = [tree]
    while stack:
        node = stack.pop()
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            yield node
        if isinstance(node, ast.If) and _is_type_checking(node.test):
            stack.extend(node.orelse)
            continue
        stack.extend(ast.iter_child_nodes(node))


def _resolve(node, module, is_package, modules):
    """The package's modules an import node loads (the deepest module it names: a
    package's ``__init__`` is its parent's business, not an edge of the importer)."""
    targets = []
    if isinstance(node, ast.Import):
        for alias in node.names:
            targets.append(_deepest(alias.name, modules))
        return [t for t in targets if t]
    if node.level:
        base = module.split(".") if is_package else module.split(".")[:-1]
        base = base[:len(base) - (node.level - 1)]
        source = ".".join(base + ([node.module] if node.module else []))
    else:
        source = node.module or ""
    for alias in node.names:
        sub = f"{source}.{alias.name}"
        targets.append(sub if sub in modules else _deepest(source, modules))
    return [t for t in targets if t]


def _deepest(name, modules):
    parts = name.split(".")
    while parts:
        candidate = ".".join(parts)
        if candidate in modules:
            return candidate
        parts.pop()
    return None


def _import_graph():
    """{module: {imported module: first line}} over the package's own modules."""
    modules = _package_modules()
    graph = {}
    for name, path in modules.items():
        edges = {}
        if path is not None:
            tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
            for node in _import_nodes(tree):
                for target in _resolve(node, name, path.name == "__init__.py", modules):
                    if target != name:
                        edges.setdefault(target, node.lineno)
        graph[name] = edges
    return graph, modules


GRAPH, MODULES = _import_graph()


def _cycles(graph):
    """Strongly connected components of more than one module (Tarjan), each as one
    concrete cycle through it: [m0, m1, ..., m0]."""
    index, low, on_stack, stack, comps = {}, {}, set(), [], []
    counter = [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on_stack.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                comps.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return [_one_cycle(graph, set(comp), comp[0]) for comp in comps]


def _one_cycle(graph, comp, start):
    """A shortest path start -> ... -> start inside one strongly connected component."""
    prev, frontier = {start: None}, [start]
    while frontier:
        nxt = []
        for v in frontier:
            for w in sorted(graph[v]):
                if w == start:
                    path = [v]
                    while prev[path[-1]] is not None:
                        path.append(prev[path[-1]])
                    return [start, *reversed(path[:-1]), start] if len(path) > 1 else [start, v, start]
                if w in comp and w not in prev:
                    prev[w] = v
                    nxt.append(w)
        frontier = nxt
    return [start]


def _area(module):
    rel = module[len(PACKAGE) + 1:] if module != PACKAGE else ""
    parts = rel.split(".") if rel else []
    while parts:
        key = ".".join(parts)
        if key in LAYOUT:
            return key
        parts.pop()
    return ""


def _describe(cycle):
    steps = []
    for a, b in zip(cycle, cycle[1:]):
        path = MODULES.get(a)
        where = f"{path.relative_to(REPO_DIR)}:{GRAPH[a][b]}" if path else a
        steps.append(f"  {a} -> {b}   ({where})")
    return "\n".join(steps)


# ------------------------------------------------------------------------ the tests
def test_the_graph_sees_the_package():
    assert f"{PACKAGE}.core.kernels" in GRAPH
    assert f"{PACKAGE}.core.kernels" in GRAPH[f"{PACKAGE}.core.batch"]


def test_no_import_cycle():
    cycles = _cycles(GRAPH)
    report = "\n\n".join(_describe(c) for c in cycles)
    if cycles:
        print(f"{len(cycles)} import cycle(s):\n{report}")
    assert not cycles, f"import cycle(s) among the package's modules:\n{report}"


def test_layers_go_one_way():
    violations = []
    for module, edges in sorted(GRAPH.items()):
        area = _area(module)
        allowed = LAYOUT.get(area)
        if allowed is None or module in CLI_ENTRY_POINTS:   # the facade, gyrodenoise/__init__.py
            continue
        for target, line in sorted(edges.items()):
            target_area = _area(target)
            if target_area != area and target_area not in allowed:
                where = MODULES[module].relative_to(REPO_DIR)
                violations.append(f"{module} ({area or 'facade'}) imports {target} "
                                  f"({target_area or 'facade'}) at {where}:{line}")
    print("\n".join(violations))
    assert not violations, "imports against the layout:\n" + "\n".join(violations)


def test_only_the_cli_imports_the_cli():
    offenders = [f"{m} imports {t}" for m, edges in GRAPH.items()
                 if _area(m) != "cli" and m not in CLI_ENTRY_POINTS
                 for t in edges if _area(t) == "cli"]
    assert not offenders, "\n".join(offenders)


# what a module of the package must not name: places outside the installed package
OUTSIDE_WORDS = ("../shared", "shared/data", "fmu_src", "REPO_DIR", "benchmarks")
_PARENTS_INDEX = re.compile(r"__file__\W*\)?\s*(?:\.resolve\(\))?\s*\.parents\[(\d+)\]")
_PARENT_CHAIN = re.compile(r"__file__\W*\)?\s*(?:\.resolve\(\))?((?:\s*\.parent\b)+)")
_DIRNAME_CHAIN = re.compile(r"((?:os\.path\.dirname\(\s*)+)(?:os\.path\.(?:abspath|realpath)\(\s*)?__file__")
_PACKAGE_PARENT = re.compile(r"\b\w*PACKAGE\w*\s*\.\s*parents?\b")


def _levels_above(text, depth):
    """Reasons a module ``depth`` folders below the package root reads above it."""
    found = []
    for m in _PARENTS_INDEX.finditer(text):          # Path(__file__).parents[k]: k = depth is the root
        if int(m.group(1)) > depth:
            found.append(m.group(0))
    for m in _PARENT_CHAIN.finditer(text):           # .parent x n = parents[n - 1]
        if m.group(1).count(".parent") - 1 > depth:
            found.append(m.group(0))
    for m in _DIRNAME_CHAIN.finditer(text):          # dirname x n = parents[n - 1]
        if m.group(1).count("dirname") - 1 > depth:
            found.append(m.group(0))
    found.extend(m.group(0) for m in _PACKAGE_PARENT.finditer(text))
    return found


def test_package_stands_alone():
    problems = []
    for path in sorted(PACKAGE_DIR.rglob("*")):
        if path.suffix not in (".py", ".c", ".h") or "__pycache__" in path.parts:
            continue
        text = path.read_text(encoding="utf-8", errors="replace")
        rel = path.relative_to(REPO_DIR)
        depth = len(path.relative_to(PACKAGE_DIR).parts) - 1
        for lineno, line in enumerate(text.splitlines(), start=1):
            for word in OUTSIDE_WORDS:
                if word in line:
                    problems.append(f"{rel}:{lineno}: names {word!r}: {line.strip()}")
        for what in _levels_above(text, depth):
            problems.append(f"{rel}: reads above the package root: {' '.join(what.split())}")
    print("\n".join(problems))
    assert not problems, "the package reaches outside itself:\n" + "\n".join(problems)


def test_levels_above_counts_from_the_module():
    assert _levels_above("Path(__file__).resolve().parents[2]", 1)
    assert not _levels_above("Path(__file__).resolve().parents[1]", 1)
    assert _levels_above("Path(__file__).parent.parent", 0)
    assert not _levels_above("Path(__file__).parent", 0)
    assert _levels_above("os.path.dirname(os.path.dirname(os.path.abspath(__file__)))", 0)
    assert _levels_above("ROOT = PACKAGE_DIR.parent / 'x'", 3)


# the word "issue" and a number, "issue" "#" number, or a number in brackets after "#"
ISSUE_NUMBER = re.compile(r"\bissues?[\s_#-]*\d+|\(#\d+\)", re.IGNORECASE)
TEXT_SUFFIXES = {".py", ".c", ".h", ".md", ".rst", ".txt", ".toml", ".yml", ".yaml", ".cfg", ".ini", ".sh",
                 ".json", ".html", ".j2"}
SKIP_DIRS = {"__pycache__", "site", "build", "dist", "node_modules"}


def _text_files(root):
    for folder, dirs, files in os.walk(root):
        dirs[:] = [d for d in dirs if not d.startswith(".") and d not in SKIP_DIRS
                   and not d.endswith(".egg-info")]
        for name in files:
            path = Path(folder, name)
            if path.suffix in TEXT_SUFFIXES and path.stat().st_size < 2_000_000:
                yield path


def test_issue_number_pattern():
    word = "issue"        # the examples are assembled so that this file names no issue number
    for text in (f"{word.title()} 23", f"{word} #21", "see (" + "#12)", f"{word.upper()}S 4", f"the {word}-12 goal"):
        assert ISSUE_NUMBER.search(text), text
    for text in ("t" + word + " 3", "issued", "color #123456", "[#1]"):
        assert not ISSUE_NUMBER.search(text), text


def test_no_issue_numbers():
    roots = [PACKAGE_DIR] + [REPO_DIR / d for d in ("tests", "benchmarks", "docs")]
    files = [p for r in roots if r.is_dir() for p in _text_files(r)]
    files += [p for p in REPO_DIR.glob("*.md")]
    hits = []
    for path in sorted(set(files)):
        text = path.read_text(encoding="utf-8", errors="replace")
        for lineno, line in enumerate(text.splitlines(), start=1):
            if ISSUE_NUMBER.search(line):
                hits.append(f"{path.relative_to(REPO_DIR)}:{lineno}: {line.strip()[:100]}")
    print(f"{len(hits)} line(s) name an issue number:\n" + "\n".join(hits))
    assert not hits, f"{len(hits)} line(s) name an issue number:\n" + "\n".join(hits[:50])
