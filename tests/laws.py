"""The physical laws of acl/physics, read from the code: every public function whose one-line docstring cites a
source (paper equation, article, textbook).  ``python tests/laws.py --update`` rewrites docs/explanation/laws.md
from it; tests/test_laws.py checks that the page is in sync and that no law is implemented twice.

A function *implements* the law of its primary source (the first citation on its docstring's first line) unless it
calls a function of acl.physics with the same primary source (then it *uses* that law: an inverse, a derivative, a
batched form written on top of the one implementation).
"""
from __future__ import annotations

import ast
import re
import sys
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PHYSICS = ROOT / "acl" / "physics"
PAGE = ROOT / "docs" / "explanation" / "laws.md"
# numerical methods, not physics (acl.physics.roots: the one numerics module) and the tie rule
NOT_LAWS = {"roots", "ties"}

_PAPER = re.compile(r"\b(paper|Suppl\.)\s+(Eq|Fig|Note)s?\.?\s*\(?([0-9][0-9.a-z]*)\)?")
_AUTHOR_YEAR = re.compile(r"\b([A-Z][a-z]+(?:\s+(?:&|and)\s+[A-Z][a-z]+|\s+et al\.)?)"
                          r"(?:,[^()]*?)?[\s,(]+(1[89]\d\d|20\d\d)\b")
_TEXTBOOK = re.compile(r"\b([A-Z][a-z]+(?:\s+(?:&|and)\s+[A-Z][a-z]+|\s+et al\.)?)"
                       r"(?:,\s*[A-Z][^(),;]*?)?\s+(?:§\s*\d+|ch\.\s*\d+|Ch\.\s*\d+|Sec\.\s*\d+|section\s+\d+|\d+\.\d+)")
_HOOKE = re.compile(r"Hooke's law")
# a textbook or article named by author and title: "Schlichting, Boundary-Layer Theory", "Kinsler et al."
_TITLED = re.compile(r"\b([A-Z][a-z]+(?:\s+(?:&|and)\s+[A-Z][a-z]+)?),\s+(?:The\s+)?[A-Z][a-z]+[-\s][A-Z]?[a-z]+")
_ETAL = re.compile(r"\b([A-Z][a-z]+ et al\.)")


def primary_source(line: str) -> str | None:
    """The first citation on a docstring line, normalised ('paper Eq. 1', 'Crum 1975', 'Lamb', "Hooke's law")."""
    hits = []
    for m in _PAPER.finditer(line):
        kind = {"Eq": "Eq.", "Fig": "Fig.", "Note": "Note"}[m.group(2)]
        hits.append((m.start(), f"{m.group(1)} {kind} {m.group(3).rstrip('.')}"))
    for m in _AUTHOR_YEAR.finditer(line):
        hits.append((m.start(), f"{m.group(1)} {m.group(2)}"))
    for m in _TEXTBOOK.finditer(line):
        hits.append((m.start(), m.group(1)))
    for m in _TITLED.finditer(line):
        hits.append((m.start(), m.group(1)))
    for m in _ETAL.finditer(line):
        hits.append((m.start(), m.group(1)))
    for m in _HOOKE.finditer(line):
        hits.append((m.start(), "Hooke's law"))
    return min(hits)[1] if hits else None


@dataclass(frozen=True)
class Law:
    module: str           # acl.physics.<module>
    name: str             # function name
    source: str           # primary source, normalised
    line: str             # first docstring line
    uses: str | None      # the acl.physics function of the same source it calls, if any

    @property
    def qualname(self) -> str:
        return f"{self.module}.{self.name}"


def _aliases(tree: ast.AST) -> dict[str, str]:
    """Local name -> imported name of every ``from ... import name as local`` in a module (at any depth)."""
    return {a.asname: a.name for node in ast.walk(tree) if isinstance(node, ast.ImportFrom)
            for a in node.names if a.asname}


def _calls(fn: ast.FunctionDef, aliases: dict[str, str] | None = None) -> set[str]:
    out = set()
    for node in ast.walk(fn):
        if isinstance(node, ast.Call):
            f = node.func
            if isinstance(f, ast.Name):
                out.add((aliases or {}).get(f.id, f.id))
            elif isinstance(f, ast.Attribute):
                out.add(f.attr)
    return out


def _reach(node: ast.FunctionDef, private: dict[str, ast.FunctionDef], aliases: dict[str, str] | None = None) -> set[str]:
    """Names called by ``node`` and, through them, by the module's private functions it calls (import aliases resolved)."""
    seen, todo, out = set(), [node], set()
    while todo:
        fn = todo.pop()
        for name in _calls(fn, aliases):
            out.add(name)
            if name in private and name not in seen:
                seen.add(name)
                todo.append(private[name])
    return out


def collect() -> list[Law]:
    """Every cited public function of acl/physics, in module then source order."""
    funcs = []
    for path in sorted(PHYSICS.glob("*.py")):
        if path.stem in NOT_LAWS or path.stem.startswith("_"):
            continue
        tree = ast.parse(path.read_text())
        private = {n.name: n for n in tree.body if isinstance(n, ast.FunctionDef) and n.name.startswith("_")}
        aliases = _aliases(tree)
        for node in tree.body:
            if isinstance(node, ast.FunctionDef) and not node.name.startswith("_"):
                doc = (ast.get_docstring(node) or "").strip().splitlines()
                first = doc[0] if doc else ""
                src = primary_source(first)
                if src:
                    funcs.append((f"acl.physics.{path.stem}", node, src, first, _reach(node, private, aliases)))
    by_name: dict[str, list] = {}
    for mod, node, src, _, _ in funcs:
        by_name.setdefault(node.name, []).append((mod, src))
    laws = []
    for mod, node, src, first, reach in funcs:
        uses = None
        for callee in sorted(reach):
            for cmod, csrc in by_name.get(callee, ()):
                if csrc == src and not (cmod == mod and callee == node.name):
                    uses = f"{cmod}.{callee}"
                    break
            if uses:
                break
        laws.append(Law(mod, node.name, src, first, uses))
    return laws


def duplicates(laws: list[Law]) -> dict[str, list[str]]:
    """Primary source -> the functions that implement it (not merely use it), where there is more than one."""
    impl: dict[str, list[str]] = {}
    for law in laws:
        if law.uses is None:
            impl.setdefault(law.source, []).append(law.qualname)
    return {s: fs for s, fs in impl.items() if len(fs) > 1}


def _cell(text: str) -> str:
    return text.replace("|", "\\|").replace("``", "`")


def render(laws: list[Law]) -> str:
    """The page docs/explanation/laws.md."""
    out = ["# The physical laws and where each one lives", "",
           "Every law the compiler, the analysis, the fit and the sweep compute with is written once, in `acl/physics/`, "
           "as a function over arrays whose leading axes are any batch (design points, data rows, waypoints, band "
           "draws).  This page is generated from the code: one row per function whose docstring cites its source.  "
           "*Implements* marks the one function that writes a law down; a function that *uses* a law calls that one "
           "(its inverse, derivative or a composition).  acl's test suite fails when this page and the code differ, "
           "or when a second function implements a source that another already implements (a few named "
           "exceptions aside, each with its reason).",
           "", "The numerical methods (root finding, golden section, Illinois) live in `acl/physics/roots.py`.", ""]
    mod = None
    for law in laws:
        if law.module != mod:
            mod = law.module
            out += ["", f"## `{mod}`", "", "| Function | Source | Role | Law (docstring) |", "|---|---|---|---|"]
        role = "implements" if law.uses is None else f"uses `{law.uses.rsplit('.', 1)[1]}`"
        out.append(f"| `{law.name}` | {_cell(law.source)} | {role} | {_cell(law.line)} |")
    return "\n".join(out) + "\n"


if __name__ == "__main__":
    text = render(collect())
    if "--update" in sys.argv:
        PAGE.write_text(text)
        print(f"wrote {PAGE.relative_to(ROOT)}")
    else:
        sys.stdout.write(text)
    for src, fs in duplicates(collect()).items():
        print(f"implemented more than once: {src}: {', '.join(fs)}", file=sys.stderr)
