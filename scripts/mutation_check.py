"""A bounded mutation run: small injected defects in the core's plain-Python kernels and the
flight-log readers, each run against the quick tests that claim to check that file; a defect
no test notices (a survivor) is a place where the tests cannot fail.

    python scripts/mutation_check.py                    # every target, ~12 min on 2 cores
    python scripts/mutation_check.py --budget-s 120 --target gyrodenoise/flightlog/tlog.py
    python scripts/mutation_check.py --list             # the mutation points, nothing run

Our own small AST mutator (mutmut and cosmic-ray want a project layout and a run time we do
not have on a shared 2-core machine). A mutant is one of: a comparison flipped (< <=, > >=,
== !=, is / is not, in / not in), an arithmetic operator swapped (+ -, * /, // /), a number
constant moved (c -> c + 1, or 2 c where adding 1 is no change), a boolean constant negated,
and / or swapped, a `not` dropped, or a simple statement of a function (assignment,
augmented assignment, call) replaced by ``pass``. The mutants are drawn at random (seeded)
from every point of a file until the file's share of the time budget is spent; each runs in
a copy of the repository (the file unparsed with the one change), ``pytest -x -m "not slow"
-n 0`` on the target's tests: killed when a test fails, a time-out (3 x the clean run, at
least 30 s) counted apart. Prints, per file, killed / survived / timed out and the score
(killed + timed out over run), and every survivor (line, mutation) to look at; ``--json PATH``
writes the same.
"""

from __future__ import annotations

import argparse
import ast
import json
import os
import random
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


@dataclass(frozen=True)
class Target:
    """A file mutated and the quick tests that claim to check it (share: of the budget)."""
    path: str
    tests: tuple[str, ...]
    share: float


TARGETS = (
    Target("gyrodenoise/core/kernels.py",
           ("tests/core/test_kernels.py", "tests/core/test_c_core_equals_python.py",
            "tests/core/test_lowpass.py", "tests/core/test_rls.py", "tests/core/test_motion.py",
            "tests/core/test_spectral_floor.py", "tests/core/test_rigid_body_band.py"),
           0.45),
    Target("gyrodenoise/flightlog/dataflash.py",
           ("tests/flightlog/test_logdata.py", "tests/flightlog/test_file_mode.py",
            "tests/flightlog/test_parameters.py", "tests/flightlog/test_segments.py"),
           0.25),
    Target("gyrodenoise/flightlog/tlog.py",
           ("tests/flightlog/test_logdata.py", "tests/flightlog/test_file_mode.py",
            "tests/flightlog/test_dropouts.py", "tests/flightlog/test_signing.py",
            "tests/flightlog/test_parameters.py"),
           0.30),
)

COMPARE_SWAP = {ast.Lt: ast.LtE, ast.LtE: ast.Lt, ast.Gt: ast.GtE, ast.GtE: ast.Gt,
                ast.Eq: ast.NotEq, ast.NotEq: ast.Eq, ast.Is: ast.IsNot, ast.IsNot: ast.Is,
                ast.In: ast.NotIn, ast.NotIn: ast.In}
BINOP_SWAP = {ast.Add: ast.Sub, ast.Sub: ast.Add, ast.Mult: ast.Div, ast.Div: ast.Mult,
              ast.FloorDiv: ast.Div}
BOOLOP_SWAP = {ast.And: ast.Or, ast.Or: ast.And}


def _moved(c):
    """A number constant moved: c + 1, or 2 c where adding 1 changes nothing (1e300)."""
    return c + 1 if c + 1 != c else 2 * c


@dataclass(frozen=True)
class Mutation:
    """One change: the ``index``-th node (ast.walk order) of the parsed file, and how."""
    index: int
    kind: str
    line: int
    what: str


def _docstring_nodes(tree):
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            body = node.body
            if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant):
                out.add(id(body[0]))
    return out


def _annotation_nodes(tree):
    """Nodes inside annotations, decorators and ``__future__`` imports: not mutated."""
    out = set()
    for node in ast.walk(tree):
        roots = []
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            roots += [a.annotation for a in node.args.args + node.args.kwonlyargs if a.annotation]
            roots += list(node.decorator_list) + ([node.returns] if node.returns else [])
        elif isinstance(node, ast.AnnAssign):
            roots.append(node.annotation)
        for r in roots:
            out.update(id(n) for n in ast.walk(r))
    return out


def mutation_points(tree):
    """Every mutation of the file, in a stable order."""
    skip = _annotation_nodes(tree)
    docs = _docstring_nodes(tree)
    in_functions = {id(n) for f in ast.walk(tree) if isinstance(f, (ast.FunctionDef, ast.AsyncFunctionDef))
                    for n in ast.walk(f)}     # a module-level constant dropped only fails the import
    points = []
    for index, node in enumerate(ast.walk(tree)):
        if id(node) in skip:
            continue
        line = getattr(node, "lineno", 0)
        if isinstance(node, ast.Compare):
            for k, op in enumerate(node.ops):
                if type(op) in COMPARE_SWAP:
                    points.append(Mutation(index, f"compare:{k}", line,
                                           f"{type(op).__name__} -> {COMPARE_SWAP[type(op)].__name__}"))
        elif isinstance(node, ast.BinOp) and type(node.op) in BINOP_SWAP:
            points.append(Mutation(index, "binop", line,
                                   f"{type(node.op).__name__} -> {BINOP_SWAP[type(node.op)].__name__}"))
        elif isinstance(node, ast.AugAssign) and type(node.op) in BINOP_SWAP:
            points.append(Mutation(index, "augop", line,
                                   f"{type(node.op).__name__}= -> {BINOP_SWAP[type(node.op)].__name__}="))
        elif isinstance(node, ast.BoolOp):
            points.append(Mutation(index, "boolop", line,
                                   f"{type(node.op).__name__} -> {BOOLOP_SWAP[type(node.op)].__name__}"))
        elif isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.Not):
            points.append(Mutation(index, "not", line, "not x -> x"))
        elif isinstance(node, ast.Constant) and type(node.value) in (int, float):
            points.append(Mutation(index, "const", line, f"{node.value!r} -> {_moved(node.value)!r}"))
        elif isinstance(node, ast.Constant) and type(node.value) is bool:
            points.append(Mutation(index, "bool", line, f"{node.value} -> {not node.value}"))
        if id(node) in in_functions and (isinstance(node, (ast.Assign, ast.AugAssign)) or (
                isinstance(node, ast.Expr) and id(node) not in docs and isinstance(node.value, ast.Call))):
            points.append(Mutation(index, "drop", line, f"{type(node).__name__} -> pass"))
    return points


class _Apply(ast.NodeTransformer):
    def __init__(self, mutation, nodes):
        self.m = mutation
        self.target = nodes[mutation.index]

    def visit(self, node):
        if node is not self.target:
            return super().visit(node)
        kind = self.m.kind
        if kind.startswith("compare:"):
            k = int(kind.split(":")[1])
            node.ops[k] = COMPARE_SWAP[type(node.ops[k])]()
        elif kind in ("binop", "augop"):
            node.op = BINOP_SWAP[type(node.op)]()
        elif kind == "boolop":
            node.op = BOOLOP_SWAP[type(node.op)]()
        elif kind == "not":
            return node.operand
        elif kind == "const":
            return ast.copy_location(ast.Constant(_moved(node.value)), node)
        elif kind == "bool":
            return ast.copy_location(ast.Constant(not node.value), node)
        elif kind == "drop":
            return ast.copy_location(ast.Pass(), node)
        return node


def mutate(source, mutation=None):
    """The file's source with one mutation, or none (unparsed: comments and layout are lost)."""
    tree = ast.parse(source)
    if mutation is not None:
        tree = ast.fix_missing_locations(_Apply(mutation, list(ast.walk(tree))).visit(tree))
    return ast.unparse(tree)


def _copy_repository(dest):
    """The tracked files and the compiled extensions, into dest/repo; ../shared beside it."""
    files = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, check=True,
                           capture_output=True).stdout.decode().split("\0")
    files += [str(p.relative_to(ROOT)) for p in (ROOT / "gyrodenoise").rglob("*.so")]
    repo = dest / "repo"
    for f in filter(None, files):
        src = ROOT / f
        (repo / f).parent.mkdir(parents=True, exist_ok=True)
        if src.is_symlink():                              # gyrodenoise/data -> ../models
            (repo / f).symlink_to(os.readlink(src))
        elif src.is_file():
            shutil.copy2(src, repo / f)
    shared = (ROOT.parent / "shared").resolve()
    if shared.is_dir():
        (dest / "shared").symlink_to(shared)
    return repo


def _run_tests(repo, tests, timeout_s):
    """('passed' | 'failed' | 'timeout', seconds) of the quick tests in the copy."""
    cmd = [sys.executable, "-m", "pytest", "-x", "-q", "-n", "0", "-p", "no:cacheprovider",
           "-m", "not slow", "--no-header", "-o", "addopts=", *tests]
    t0 = time.monotonic()
    proc = subprocess.Popen(cmd, cwd=repo, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            start_new_session=True)
    try:
        rc = proc.wait(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
        return "timeout", time.monotonic() - t0
    return ("passed" if rc == 0 else "failed"), time.monotonic() - t0


@dataclass
class FileScore:
    path: str
    points: int
    killed: int = 0
    timed_out: int = 0
    survivors: list = field(default_factory=list)

    @property
    def run(self):
        return self.killed + self.timed_out + len(self.survivors)

    @property
    def score(self):
        return (self.killed + self.timed_out) / self.run if self.run else float("nan")


def check_target(repo, target, budget_s, rng, log):
    path = repo / target.path
    original = path.read_text()
    points = mutation_points(ast.parse(original))
    rng.shuffle(points)
    result = FileScore(target.path, len(points))
    pyc = path.parent / "__pycache__"
    try:
        path.write_text(mutate(original))    # the unparsed file itself
        status, clean_s = _run_tests(repo, target.tests, None)
        if status != "passed":
            raise SystemExit(f"{target.path}: the quick tests fail on the unmutated (unparsed) file")
        timeout_s = max(30.0, 3.0 * clean_s)
        log(f"{target.path}: {len(points)} mutation points; clean run {clean_s:.1f} s; budget {budget_s:.0f} s")
        deadline = time.monotonic() + budget_s
        for m in points:
            if time.monotonic() > deadline:
                break
            path.write_text(mutate(original, m))
            shutil.rmtree(pyc, ignore_errors=True)             # never a stale compiled copy
            status, dt = _run_tests(repo, target.tests, timeout_s)
            if status == "failed":
                result.killed += 1
            elif status == "timeout":
                result.timed_out += 1
            else:
                result.survivors.append(m)
            log(f"  line {m.line:4d} {m.kind:10s} {m.what:28s} {status:8s} {dt:5.1f} s")
    finally:
        path.write_text(original)
        shutil.rmtree(pyc, ignore_errors=True)
    return result


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--budget-s", type=float, default=720.0, help="time for every target together")
    ap.add_argument("--seed", type=int, default=38)
    ap.add_argument("--target", action="append", help="only this file (repeatable)")
    ap.add_argument("--json", type=Path, help="write the scores and survivors here")
    ap.add_argument("--list", action="store_true", help="print the mutation points and stop")
    a = ap.parse_args(argv)
    targets = [t for t in TARGETS if not a.target or t.path in a.target]
    if not targets:
        ap.error(f"--target: none of {a.target} is a target ({', '.join(t.path for t in TARGETS)})")
    if a.list:
        for t in targets:
            for m in mutation_points(ast.parse((ROOT / t.path).read_text())):
                print(f"{t.path}:{m.line}: {m.kind} {m.what}")
        return 0
    share = sum(t.share for t in targets)

    def log(line):
        print(line, flush=True)

    scores = []
    with tempfile.TemporaryDirectory(prefix="gyrodenoise-mutation-") as tmp:
        repo = _copy_repository(Path(tmp))
        for t in targets:
            scores.append(check_target(repo, t, a.budget_s * t.share / share, random.Random(a.seed), log))
    print("\nfile                                  points    run  killed  timeout  survived  score")
    for s in scores:
        print(f"{s.path:36s} {s.points:7d} {s.run:6d} {s.killed:7d} {s.timed_out:8d} {len(s.survivors):9d}"
              f"  {s.score:5.0%}")
    for s in scores:
        for m in sorted(s.survivors, key=lambda m: m.line):
            print(f"survived: {s.path}:{m.line}: {m.kind} {m.what}")
    if a.json:
        a.json.write_text(json.dumps([{"file": s.path, "points": s.points, "run": s.run,
                                       "killed": s.killed, "timed_out": s.timed_out,
                                       "survived": [vars(m) for m in s.survivors]}
                                      for s in scores], indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
