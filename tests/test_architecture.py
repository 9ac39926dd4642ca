"""The package's shape: imports flow one way, scenario -> core -> masters -> kernel, never back up;
no import cycle between modules; only the kernel and the FMI layer know the C ABI (import ctypes);
at most 12 modules at the top of the package."""
import ast
import ctypes
import os
import re
from pathlib import Path

import numpy as np

import wavecosim

PACKAGE = Path(wavecosim.__file__).resolve().parent
# Each part may import itself and the parts ranked below it, never one ranked above.
C_ABI = ("kernel", "fmi")     # the parts that may import ctypes
RANK = {"errors": 0, "examples": 0, "kernel": 1, "fmi": 2, "masters": 3, "core": 4, "scenario": 5, "run": 6,
        "sweeps": 7, "bench": 7, "api": 8, "cli": 8, "plots": 8, "__init__": 8, "__main__": 8}


def modules():
    """{dotted name: path} of every module of the package."""
    out = {}
    for path in PACKAGE.rglob("*.py"):
        parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
        out[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return out


def imported(name, path):
    """The package's modules that the module `name` imports (relative and absolute imports)."""
    package = name if path.name == "__init__.py" else name.rsplit(".", 1)[0]
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            if target.split(".")[0] == "wavecosim":
                yield target, [a.name for a in node.names]
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.split(".")[0] == "wavecosim":
                    yield alias.name, []


def part(name):
    """The part of the package a module belongs to: its first component below wavecosim."""
    pieces = name.split(".")
    return pieces[1] if len(pieces) > 1 else "__init__"


def edges():
    mods = modules()
    for name, path in mods.items():
        for target, names in imported(name, path):
            subs = [f"{target}.{n}" for n in names if f"{target}.{n}" in mods]
            for t in subs or [target]:
                yield name, t


def test_every_part_is_ranked():
    assert {part(m) for m in modules()} <= set(RANK)


def test_imports_never_reach_up():
    upward = [f"{a} imports {b}" for a, b in edges() if RANK[part(b)] > RANK[part(a)]]
    assert upward == []


def test_no_import_cycle():
    graph = {}
    for a, b in edges():
        if b != a:
            graph.setdefault(a, set()).add(b)
    seen, stack, cycles = set(), [], []

    def visit(node):
        if node in stack:
            cycles.append(stack[stack.index(node):] + [node])
            return
        if node in seen:
            return
        seen.add(node)
        stack.append(node)
        for nxt in sorted(graph.get(node, ())):
            visit(nxt)
        stack.pop()

    for node in sorted(graph):
        visit(node)
    assert cycles == []


def test_top_level_is_small():
    top = [p.name for p in PACKAGE.glob("*.py")]
    assert len(top) <= 12, top


def test_only_the_kernel_and_the_fmi_layer_import_ctypes():
    """Every other part passes C values made by wavecosim.kernel (cvalues, the bindings)."""
    found = []
    for name, path in modules().items():
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            names = ([a.name for a in node.names] if isinstance(node, ast.Import)
                     else [node.module or ""] if isinstance(node, ast.ImportFrom) and not node.level else [])
            if any(n.split(".")[0] == "ctypes" for n in names) and part(name) not in C_ABI:
                found.append(name)
    assert found == [], found


def tree(path):
    """The module's syntax tree (read as UTF-8: an FMU may set the C locale)."""
    return ast.parse(Path(path).read_text(encoding="utf-8"))


def own_attributes(path, classes):
    """The names the classes of a module define: methods, properties, class fields and self.X they set."""
    names = set()
    for node in ast.walk(tree(path)):
        if isinstance(node, ast.ClassDef) and node.name in classes:
            for sub in ast.walk(node):
                if isinstance(sub, (ast.FunctionDef, ast.AsyncFunctionDef)):
                    names.add(sub.name)
                elif isinstance(sub, ast.Attribute) and isinstance(sub.value, ast.Name) and sub.value.id == "self":
                    names.add(sub.attr)
                elif isinstance(sub, ast.AnnAssign) and isinstance(sub.target, ast.Name):
                    names.add(sub.target.id)
    return names


def test_the_kernels_bindings_read_no_scene_subsystem_or_fmu():
    """kernel/*.py take the scene as plain data (kernel/description.py, built by core/kernel_scene.py):
    they name no Scene, Subsystem or Fmu and touch no attribute only those classes define."""
    theirs = (own_attributes(PACKAGE / "core" / "scene.py", {"Scene"})
              | own_attributes(PACKAGE / "core" / "frozen_port_map.py", {"Subsystem"})
              | own_attributes(PACKAGE / "fmi" / "fmu.py", {"Fmu", "Fmi2", "Fmi3"}))
    kernel = PACKAGE / "kernel"
    classes = {p: {n.name for n in ast.walk(tree(p)) if isinstance(n, ast.ClassDef)} for p in kernel.glob("*.py")}
    ours = set().union(*(own_attributes(p, names) | names for p, names in classes.items()))
    common = set().union(*map(dir, (str, list, dict, Path, os, re, np.ndarray, ctypes, ctypes.CDLL)))
    foreign = theirs - ours - common - {"close", "name", "m", "n", "t", "dt", "lib", "handle"}
    found = []
    for path in sorted(kernel.glob("*.py")):
        for node in ast.walk(tree(path)):
            if isinstance(node, ast.Attribute) and node.attr in foreign:
                found.append(f"{path.name}:{node.lineno} .{node.attr}")
            if isinstance(node, ast.Name) and node.id in ("Scene", "Subsystem", "Fmu"):
                found.append(f"{path.name}:{node.lineno} {node.id}")
    assert found == [], found
