"""The package's layout rules (docs/architecture.md), read from its source:

* no import cycle between its modules, counting imports inside functions (they hide cycles);
* no module over 400 lines and no function over 60 (a newcomer reads each in one sitting);
* the gmsh mesh builders import without DOLFINx (they run on a machine that only meshes).

The import graph is read with ``ast`` (no module is imported), so a cycle is found even where
Python would tolerate it at run time.
"""
import ast
import os
import subprocess
import sys

import pytest
from conftest import REPO

PACKAGE = os.path.join(REPO, "eyeball_fenicsx")
MAX_MODULE_LINES, MAX_FUNCTION_LINES = 400, 60


def modules():
    """{dotted name: path} of every module of the package."""
    found = {}
    for folder, _, files in os.walk(PACKAGE):
        for name in files:
            if name.endswith(".py"):
                path = os.path.join(folder, name)
                parts = os.path.relpath(path, REPO)[:-3].split(os.sep)
                found[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return found


def imported(module, path, known):
    """The package modules that ``module`` imports, anywhere in its file."""
    package = module if path.endswith("__init__.py") else module.rsplit(".", 1)[0]
    targets = set()
    for node in ast.walk(ast.parse(open(path).read())):
        if isinstance(node, ast.Import):
            targets.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parent = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(parent + ([base] if base else []))
            # "from . import x" names a module; "from .m import f" names m
            targets.update(f"{base}.{alias.name}" for alias in node.names)
            targets.add(base)
    return {t for t in targets if t in known and t != module}


def find_cycle(graph):
    """One import cycle of the graph as a list of modules, or None (depth-first search)."""
    state, stack = {}, []

    def visit(node):
        state[node] = "open"
        stack.append(node)
        for nxt in sorted(graph[node]):
            if state.get(nxt) == "open":
                return stack[stack.index(nxt):] + [nxt]
            if nxt not in state and (cycle := visit(nxt)):
                return cycle
        state[node] = "done"
        stack.pop()
        return None

    for node in sorted(graph):
        if node not in state and (cycle := visit(node)):
            return cycle
    return None


def test_find_cycle_finds_one():
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": set()}) is None


def test_no_import_cycle():
    known = modules()
    graph = {m: imported(m, p, known) for m, p in known.items()}
    assert find_cycle(graph) is None, f"import cycle: {' -> '.join(find_cycle(graph))}"


def test_module_and_function_sizes():
    too_long = []
    for module, path in modules().items():
        source = open(path).read()
        lines = source.count("\n")
        if lines > MAX_MODULE_LINES:
            too_long.append(f"{module}: {lines} lines")
        for node in ast.walk(ast.parse(source)):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                length = node.end_lineno - node.lineno + 1
                if length > MAX_FUNCTION_LINES:
                    too_long.append(f"{module}.{node.name}: {length} lines")
    assert not too_long, too_long


def test_mesh_builders_import_without_dolfinx():
    code = ("import sys, pkgutil, importlib, eyeball_fenicsx.meshing.builders as b\n"
            "for m in pkgutil.iter_modules(b.__path__): importlib.import_module(f'{b.__name__}.{m.name}')\n"
            "loaded = [m for m in ('dolfinx', 'ufl', 'petsc4py') if m in sys.modules]\n"
            "assert not loaded, loaded\n")
    env = {k: v for k, v in os.environ.items() if not k.startswith(("OMPI_", "PMIX_"))}
    result = subprocess.run([sys.executable, "-c", code], cwd=REPO, env=env, capture_output=True, text=True)
    assert result.returncode == 0, result.stderr


def test_the_example_feature():
    """docs/architecture.md's example feature, run as the page shows it: the springs of the
    elastic foundation carry the whole nodal load (equilibrium, to Newton's tolerance)."""
    text = open(os.path.join(REPO, "docs", "architecture.md")).read()
    blocks = [block.split("```", 1)[0] for block in text.split("```python\n")[1:]]
    assert len(blocks) == 2
    assert 25 <= blocks[0].count("\n") <= 40  # "a minimal example feature of about 30 lines"
    namespace = {}
    exec(compile("".join(blocks), "docs/architecture.md", "exec"), namespace)
    assert namespace["equilibrium_error"] < 1e-8


def test_a_feature_that_plays_part_of_a_role_is_refused():
    """A Protocol checks only that members exist: a feature with a tangent's methods but no
    ``symmetric_tangent`` would be left out of the tangent without a word. The problem refuses it."""

    from eyeball_fenicsx.features.base import Feature
    from eyeball_fenicsx.features.roles import NodalTangent, check_whole_role

    class HalfATangent(Feature):
        name = "half"

        def coupling(self):
            return None

        def add_to_jacobian(self, A):
            pass

    refused = r"HalfATangent 'half' plays part of the role NodalTangent .* \['symmetric_tangent'\]"
    with pytest.raises(TypeError, match=refused):
        check_whole_role(HalfATangent(), NodalTangent)
    HalfATangent.symmetric_tangent = True
    check_whole_role(HalfATangent(), NodalTangent)  # the whole role: accepted


def test_readable_labels():
    """The figures a surgeon reads are named in words with their units; an unknown key keeps its text."""
    from eyeball_fenicsx.output.labels import label
    assert label("eye.max_mises_MPa.band") == "largest von Mises stress, band (MPa)"
    assert label("eye.iop_mmHg") == "IOP (mmHg)"
    assert label("band.0.reduction") == "band 1: circumference reduction (mm)"
    assert label("mesh.band_width") == "band width (mm)"
    assert label("eye.something_new") == "eye / something_new"
    assert label("materials.sclera.c.10") == "sclera: c10 (MPa)"  # a tissue's constant, as a sweep's range names it
    assert label("materials.ciliary_body.c10") == "ciliary body: c10 (MPa)"
