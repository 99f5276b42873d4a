"""The package's layers, read from the imports of every module in acl/ (imports inside functions included).

Lowest first: numerics < physics < syntax < design < analysis < {lint, schedule, fit, sweep} < emit < results <
{fmt, lsp, commands} < cli (issue 23).  A module may import its own package and any lower layer, or a package of
its own layer; never a higher one.  No private name (``_x``: a module, a function, a class, a constant) is
imported, or reached as an attribute of an imported module, from outside the package that owns it.

ALLOWED lists the violations that exist today, each with its reason; the test fails on any new one, and on an
entry that no longer occurs (remove it: the list only shrinks).
"""
from __future__ import annotations

import ast
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
ACL = ROOT / "acl"

# Lowest first.  Each entry names packages (a module belongs to the longest matching prefix).
LAYERS: list[tuple[str, tuple[str, ...]]] = [
    ("numerics", ("acl.numerics",)),
    ("physics", ("acl.physics",)),
    # the front end and the modules everything above it shares: units, diagnostics, console, files read
    ("syntax", ("acl.syntax", "acl.units", "acl._unit_table", "acl.diagnostics", "acl._console", "acl._files",
                "acl._resources", "acl._callable", "acl._display")),
    ("design", ("acl.design",)),
    ("analysis", ("acl.analysis",)),
    ("stages", ("acl.lint", "acl.schedule", "acl.fit", "acl.sweep")),
    # the emitters: schedules to files (emit), designs to print files (export), schedules to instruments and
    # video to data (bench)
    ("emit", ("acl.emit", "acl.export", "acl.bench")),
    # the typed results of the Python API (acl.notebook today)
    ("results", ("acl.results", "acl.notebook")),
    # `acl` itself (acl/__init__.py: the Python API) sits with the commands
    ("front", ("acl.fmt", "acl.lsp", "acl.commands", "acl.editor", "acl")),
    ("cli", ("acl.cli", "acl.__main__")),
]

# Known violations on 634b5c7: "importer -> imported" (a module, or module:name for a private name).
# Each is to be removed, not added to: a new edge that breaks the layers is a defect of the change that adds it.
ALLOWED: dict[str, str] = {
    # --- layer order -------------------------------------------------------------------------------------
    # acl.lint, acl.fit and acl.sweep are subpackages and API functions at once: calling the module dispatches
    # to the API function in acl/__init__.py (by design: `acl.lint(path)` works after `import acl.lint`)
    "acl._callable -> acl": "a callable subpackage calls its API function; by design",
    # design reaches up to the results for a Design's notebook display (_repr_html_, .plot()); the display
    # belongs with the results (acl.notebook), called on the Design from there
    "acl.design.model -> acl.notebook": "Design's notebook display lives in the results layer",
    # the fit and the compile/synth commands load designs through the Python API (`import acl; acl.load`)
    # instead of acl.design.resolve.load_design: to be removed by the engine work (fit's own options)
    "acl.fit.loop -> acl": "acl.load of the Python API; use acl.design.resolve",
    "acl.fit.modelcheck -> acl": "acl.loads of the Python API; use acl.design.resolve",
    "acl.fit.problem -> acl": "acl.load of the Python API; use acl.design.resolve",
    "acl.fit.synth -> acl": "acl.load of the Python API; use acl.design.resolve",
    # a stage prints a design back as canonical text with the formatter (fmt sits on the top layer although it
    # only needs syntax and design): either canonical() moves down, or fmt does
    "acl.fit.calibrated -> acl.fmt": "the calibrated design as canonical text",
    "acl.sweep.tune -> acl.fmt": "the tuned design as canonical text",
    # --- private names across packages ---------------------------------------------------------------------
    # (none left: the fit reaches the force engine through public names, acl.analysis.rows)
}


def place_of(module: str) -> tuple[str, int]:
    """The entry of LAYERS that ``module`` belongs to (the longest matching prefix; ``acl`` matches only itself, so
    a new top-level module or package must be placed) and its layer's index; ("", -1) if none."""
    best, rank = "", -1
    for i, (_, packages) in enumerate(LAYERS):
        for p in packages:
            if (module == p or p != "acl" and module.startswith(p + ".")) and len(p) > len(best):
                best, rank = p, i
    return best, rank


def layer_of(module: str) -> int:
    return place_of(module)[1]


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def is_module(name: str) -> bool:
    path = ROOT.joinpath(*name.split("."))
    return path.with_suffix(".py").is_file() or (path / "__init__.py").is_file()


def package_of(module: str) -> str:
    """The package a module is part of (a package is its own)."""
    return module if (ROOT.joinpath(*module.split(".")) / "__init__.py").is_file() else module.rsplit(".", 1)[0]


def owner_of_private(dotted: str) -> str | None:
    """The package owning the first private component of ``dotted`` (acl.a.b._c -> the package of acl.a.b)."""
    parts = dotted.split(".")
    for i, part in enumerate(parts):
        if part.startswith("_") and not (part.startswith("__") and part.endswith("__")):
            parent = ".".join(parts[:i])
            return package_of(parent) if is_module(parent) else parent
    return None


@dataclass(frozen=True)
class Edge:
    importer: str
    target: str        # the module imported (or the module of the name imported)
    name: str          # the full dotted name used (module, or module.attribute)
    path: Path
    line: int

    @property
    def where(self) -> str:
        return f"{self.path.relative_to(ROOT).as_posix()}:{self.line}"


def edges_of(path: Path) -> list[Edge]:
    importer = module_name(path)
    pkg = package_of(importer)
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    edges: list[Edge] = []
    aliases: dict[str, str] = {}           # local name -> acl module it is bound to
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                if a.name == "acl" or a.name.startswith("acl."):
                    edges.append(Edge(importer, a.name, a.name, path, node.lineno))
                    if a.asname:
                        aliases[a.asname] = a.name
                    else:                      # `import acl.x.y` binds `acl`
                        aliases["acl"] = "acl"
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = pkg.split(".")[: len(pkg.split(".")) - (node.level - 1)]
                source = ".".join(base + ([node.module] if node.module else []))
            else:
                source = node.module or ""
            if not (source == "acl" or source.startswith("acl.")):
                continue
            for a in node.names:
                full = f"{source}.{a.name}"
                if is_module(full):
                    edges.append(Edge(importer, full, full, path, node.lineno))
                    aliases[a.asname or a.name] = full
                elif full != "acl.__version__":          # the version is the package's metadata, not its API
                    edges.append(Edge(importer, source, full, path, node.lineno))
    for node in ast.walk(tree):              # a private attribute of an imported module: `acoustics._engine(...)`
        if (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id in aliases
                and node.attr.startswith("_") and not node.attr.startswith("__")):
            module = aliases[node.value.id]
            edges.append(Edge(importer, module, f"{module}.{node.attr}", path, node.lineno))
    return edges


def all_edges() -> list[Edge]:
    return [e for path in sorted(ACL.rglob("*.py")) if "__pycache__" not in path.parts for e in edges_of(path)]


def violations() -> dict[str, Edge]:
    """``"importer -> imported"`` -> the first place it happens, for every edge that breaks the rules."""
    found: dict[str, Edge] = {}
    for e in all_edges():
        (unit, rank), (target_unit, target_rank) = place_of(e.importer), place_of(e.target)
        if target_unit != unit and target_rank > rank:
            found.setdefault(f"{e.importer} -> {e.target}", e)
        owner = owner_of_private(e.name)
        if owner is not None and not (e.importer == owner or e.importer.startswith(owner + ".")):
            module, _, attr = e.name.rpartition(".")
            key = f"{e.importer} -> {module}:{attr}" if is_module(module) and not is_module(e.name) else \
                f"{e.importer} -> {e.name}"
            found.setdefault(key, e)
    return found


def test_every_module_has_a_layer():
    missing = sorted({module_name(p) for p in ACL.rglob("*.py") if "__pycache__" not in p.parts
                      and layer_of(module_name(p)) < 0})
    assert not missing, f"place these modules in LAYERS of tests/test_layers.py: {missing}"


def test_the_import_reader_sees_imports_inside_functions_and_private_attributes():
    """The reader itself: known edges of today's tree, one at module level, one inside a function, one attribute."""
    keys = {(e.importer, e.name) for e in all_edges()}
    assert ("acl.physics.beams", "acl.physics.roots.brentq") in keys                        # module level
    assert ("acl.commands.compile", "acl.schedule.compile.compile_program") in keys         # inside a function
    assert ("acl.design.model", "acl.notebook.design_html") in keys                         # inside a method
    assert layer_of("acl.physics.batch") < layer_of("acl.syntax.parser") < layer_of("acl.design.model") \
        < layer_of("acl.analysis.acoustics") < layer_of("acl.fit.forward") == layer_of("acl.sweep.table") \
        < layer_of("acl.emit.output") < layer_of("acl.notebook") < layer_of("acl.lsp.server") < layer_of("acl.cli")
    assert owner_of_private("acl.analysis.acoustics._engine") == "acl.analysis"
    assert owner_of_private("acl._files.undecodable") == "acl"          # acl's own helpers serve every package
    assert owner_of_private("acl.commands._common.report") == "acl.commands"
    assert layer_of("acl.engine") == -1 and layer_of("acl") == layer_of("acl.commands.fit")   # to be placed: a new one


def test_the_checker_finds_an_upward_import_and_a_private_attribute(tmp_path, monkeypatch):
    """On a small tree: physics importing the cli inside a function, and the fit calling analysis's private
    function through its module, are both found; analysis using physics, and its own private name, are not."""
    files = {
        "acl/__init__.py": "", "acl/cli.py": "def main(): pass\n",
        "acl/physics/__init__.py": "", "acl/analysis/__init__.py": "", "acl/fit/__init__.py": "",
        "acl/physics/beams.py": "def f():\n    from acl.cli import main\n    return main\n",
        "acl/analysis/acoustics.py": "from acl.physics import beams\n_engine = beams.f\n",
        "acl/analysis/report.py": "from acl.analysis.acoustics import _engine\n",          # its own package
        "acl/fit/group.py": "from acl.analysis import acoustics as ac\n\ndef g():\n    return ac._engine\n",
    }
    for name, text in files.items():
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text(text)
    monkeypatch.setitem(globals(), "ROOT", tmp_path)
    monkeypatch.setitem(globals(), "ACL", tmp_path / "acl")
    found = violations()
    assert set(found) == {"acl.physics.beams -> acl.cli", "acl.fit.group -> acl.analysis.acoustics:_engine"}
    assert found["acl.physics.beams -> acl.cli"].where == "acl/physics/beams.py:2"
    assert found["acl.fit.group -> acl.analysis.acoustics:_engine"].where == "acl/fit/group.py:4"


def test_no_new_layer_or_private_name_violation():
    found = violations()
    new = {k: f"{e.where}: {e.name}" for k, e in found.items() if k not in ALLOWED}
    assert not new, ("imports that break the layers (a lower layer importing a higher one) or use a private name of "
                     f"another package: {new}")


def test_the_allow_list_only_holds_violations_that_still_exist():
    gone = sorted(set(ALLOWED) - set(violations()))
    assert not gone, f"fixed: remove these entries from ALLOWED in tests/test_layers.py: {gone}"
