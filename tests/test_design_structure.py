"""The design stage runs one way (issue 11, "Structure"): a small core of shared types, then the
evaluator, the builders, the programs, the assembly, and the public `load` last. No module imports
a later one (not even inside a function), and no private name crosses a module boundary."""
from __future__ import annotations

import ast
from pathlib import Path

DESIGN = Path(__file__).resolve().parents[1] / "acl" / "design"
ORDER = ["values", "core", "modules", "evaluate", "builders", "programs", "assemble", "resolve"]


def _imports(path: Path):
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("acl.design"):
            mod = node.module.split(".")[2] if node.module.count(".") >= 2 else None
            for alias in node.names:
                yield (mod or alias.name), alias.name


def test_the_stage_imports_only_earlier_modules():
    for name in ORDER:
        for mod, _ in _imports(DESIGN / f"{name}.py"):
            if mod in ORDER:
                assert ORDER.index(mod) < ORDER.index(name), f"{name}.py imports the later {mod}.py"


def test_no_private_name_crosses_a_module_boundary():
    for path in DESIGN.glob("*.py"):
        for mod, imported in _imports(path):
            assert not imported.startswith("_"), f"{path.name} imports private `{imported}` from {mod}"
