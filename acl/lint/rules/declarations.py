"""ACL6xx: declarations never used, parameters missing their units, and failing `require`s."""
from __future__ import annotations

import re

import numpy as np


from acl.design.model import Drive, Tone
from acl.diagnostics import Severity, Span
from acl.lint.context import Context, khz
from acl.lint.registry import rule
from acl.lint.source import NUMBER_ONLY

CHECKED_KINDS = ("material", "medium", "transducer", "spring", "truss", "anchor", "param", "import")


@rule("ACL601", "unused-declaration",
      "a declaration nothing refers to is dead weight, or a sign that a reference names the wrong thing",
      Severity.WARNING, "declarations")
def unused_declaration(ctx: Context):
    src = ctx.source
    if src is None:
        return
    if is_library(ctx):
        ctx.note("ACL601", "a library module (no program, joint or `use`): its declarations are for importers")
        return
    used = {u.name for u in src.uses}
    d = ctx.design
    auto = {x.name for x in (d.medium, d.transducer) if x is not None}
    replaced = _declared_by_bases(src)
    for decl in src.declarations:
        if decl.kind not in CHECKED_KINDS or decl.name in used or decl.name in auto:
            continue
        if decl.kind == "param" and decl.name in replaced:
            continue            # redeclares a base's parameter (`extends`): used where the base uses it
        what = "parameter" if decl.kind == "param" else decl.kind
        hint = {"import": "remove the import", "medium": "`use medium NAME` it or remove it",
                "transducer": "`use transducer NAME` it or remove it"}.get(decl.kind, "use it or remove it")
        yield ctx.finding("ACL601", f"{what} `{decl.name}` is never used", Span(file=src.path, line=decl.line,
                          column=decl.column, end_line=decl.line, end_column=decl.column + len(decl.name)),
                          hint=hint)


_EXTENDS = re.compile(r'^\s*extends\s+"([^"]+)"')


def _declared_by_bases(src, depth: int = 0) -> set[str]:
    """Parameter names declared by the designs this file `extends` (transitively): a redeclaration
    replaces the base's value (acl fit's calibrated and acl tune's tuned designs), so it is used
    wherever the base uses the name."""
    import os

    from acl.lint.source import scan

    names: set[str] = set()
    for line in src.lines:
        m = _EXTENDS.match(line)
        if not m or depth > 8:
            continue
        base = os.path.join(os.path.dirname(os.path.abspath(src.path)), m.group(1))
        try:
            with open(base, encoding="utf-8") as fh:
                text = fh.read(4_000_000)
        except (OSError, UnicodeDecodeError):
            continue
        bsrc = scan(base, text)
        names |= {d.name for d in bsrc.declarations if d.kind == "param"} | _declared_by_bases(bsrc, depth + 1)
    return names


def is_library(ctx: Context) -> bool:
    """A module that only declares things for others to import: no program, no joint, no `use`."""
    d = ctx.design
    uses = any(re.match(r"\s*use\s", line) for line in ctx.source.code)
    return not d.programs and not d.joints and not uses


_DIMLESS_STEP = re.compile(r"\b(phase|margin)\s*$")


def _quantity_context(use, units: dict[str, str]) -> bool | None:
    """Whether the place of ``use`` expects a dimensioned quantity (None: cannot tell)."""
    from acl.design.resolve import SCHEMAS

    if use.block == "program":
        return not _DIMLESS_STEP.search(use.before)
    if use.block in SCHEMAS and use.key:
        if use.key == "section":
            return True                       # circle(d) / rect(w, t): lengths
        spec = SCHEMAS[use.block].get(use.key)
        if spec is None or spec.unit is None:
            return None
        return spec.unit != ""
    if use.block is None and use.statement == "param" and use.statement_name in units:
        return units[use.statement_name] != ""
    if use.block is None and use.statement == "require":
        return "margin(" not in use.before
    return None


@rule("ACL602", "param-without-unit",
      "a bare-number parameter used only where quantities are expected hides its unit in every expression",
      Severity.WARNING, "declarations")
def param_without_unit(ctx: Context):
    src = ctx.source
    if src is None:
        return
    units = {p.name: p.unit for p in ctx.design.params}
    for decl in src.declarations:
        if decl.kind != "param" or units.get(decl.name) != "" or not NUMBER_ONLY.match(decl.value):
            continue
        uses = [u for u in src.uses if u.name == decl.name]
        if uses and all(_quantity_context(u, units) for u in uses):
            yield ctx.finding("ACL602", f"parameter `{decl.name}` is a bare number but is used only as a quantity",
                              Span(file=src.path, line=decl.line, column=decl.column),
                              notes=[f"used at line(s) {', '.join(str(u.line) for u in uses)}"],
                              hint=f"give it its unit (e.g. `param {decl.name} = {decl.value} um`) and drop the "
                                   "unit factors where it is used")


@rule("ACL603", "require-failed",
      "a `require` states design intent; the predicted design does not meet it",
      Severity.ERROR, "declarations")
def require_failed(ctx: Context):
    d = ctx.design
    for r in d.requires:
        value, unit, extra = _evaluate(ctx, r)
        if value is None:
            continue
        ok = (r.lower is None or value >= r.lower) and (r.upper is None or value <= r.upper)
        if ok:
            continue
        fmt = {"Hz": khz, "m": lambda x: f"{x * 1e6:.3g} um"}.get(unit, lambda x: f"{x:.3g}")
        shown = fmt(value)
        bounds = " .. ".join("" if b is None else fmt(b) for b in (r.lower, r.upper))
        yield ctx.finding("ACL603", f"`{r.text}` fails: predicted {shown}", r.span,
                          notes=[f"required range {bounds}", *extra],
                          hint="change the design or the requirement")


def _evaluate(ctx: Context, r):
    d = ctx.design
    if r.kind == "resonance":
        modes = ctx.modes(d.capsule(r.args[0]))
        if r.mode >= len(modes):
            return float("nan"), "Hz", [f"capsule `{r.args[0]}` has {len(modes)} mode(s)"]
        m = modes[r.mode]
        return m.frequency_hz, "Hz", [f"mode {r.mode + 1}: {khz(m.frequency_hz)}, Q = {m.q:.3g}, "
                                      f"dominant orifice `{m.dominant_orifice}`"]
    if r.kind == "separation" and len(r.args) == 1:
        fs = sorted(m.frequency_hz for m in ctx.modes(d.capsule(r.args[0])))
        if len(fs) < 2:
            return float("nan"), "Hz", [f"capsule `{r.args[0]}` has {len(fs)} distinct mode(s)"]
        gaps = [b - a for a, b in zip(fs, fs[1:])]
        return min(gaps), "Hz", ["adjacent modes " + ", ".join(khz(f) for f in fs)]
    if r.kind == "separation":
        fa = ctx.modes(d.capsule(r.args[0]))[0].frequency_hz
        fb = ctx.modes(d.capsule(r.args[1]))[0].frequency_hz
        return abs(fa - fb), "Hz", [f"first modes {khz(fa)} and {khz(fb)}"]
    if r.kind == "margin":
        from acl.lint.rules.latches import _carried, _needed, _push, landscape

        latch = d.latch(r.args[0])
        if d.transducer is None:
            ctx.note("ACL603", f"`{r.text}`: no transducer, so no maximum voltage to judge the margin")
            return None, "", []
        land = landscape(ctx, latch)
        needed = _needed(land, latch.state)
        if not land.bistable or needed is None or needed <= 0:
            return 0.0, "", [f"latch `{latch.name}` is not bistable"]
        v = d.transducer.max_voltage
        best = 0.0
        for c in _carried(ctx, latch):
            for m in ctx.modes(d.capsule(c)):
                best = max(best, _push(ctx, latch, Drive(tones=(Tone(frequency=m.frequency_hz, amplitude=v),)),
                                       latch.state))
        return best / needed, "", [f"best push {best * 1e9:.3g} nN at {v:.3g} V on a carried mode; "
                                   f"switching needs {needed * 1e9:.3g} nN"]
    return _gap(ctx, r)


def _gap(ctx: Context, r):
    """Smallest gap between the two orifices over the equilibria of every program step with a known drive."""
    if not ctx.config.mechanics:
        ctx.note("ACL603", f"`{r.text}`: gap requirements need the equilibrium (`mechanics = true` or --mechanics)")
        return None, "", []
    try:
        from acl.analysis.acoustics import force_model_for
        from acl.analysis.mechanics import equilibrium
    except ImportError as exc:  # pragma: no cover - analysis not installed
        ctx.note("ACL603", f"`{r.text}`: mechanics analysis unavailable ({exc})")
        return None, "", []
    from acl.diagnostics import DiagnosticError

    d = ctx.design
    (ca, oa), (cb, ob) = (x.split(".") for x in r.args)
    pa, pb = np.asarray(d.capsule(ca).orifice(oa).center), np.asarray(d.capsule(cb).orifice(ob).center)
    worst, where, skipped = None, "", 0
    for p, st in ctx.steps():
        drives = ctx.step_drives(st)
        if not drives and st.kind in ("follow", "hold", "switch"):
            skipped += 1
        for drive in drives:
            key = ("equilibrium", tuple((t.frequency, t.amplitude, t.phase) for t in drive.tones))
            try:
                state = ctx.cached(key, lambda: equilibrium(d, drive, force_model_for(d)))
            except DiagnosticError as exc:
                ctx.note("ACL603", f"`{r.text}`: mechanism not analysable ({exc})")
                return None, "", []
            da, db = (np.asarray(state.displacements[c]) for c in (ca, cb))
            gap = float(np.linalg.norm((pb + db) - (pa + da)))
            if state.status == "snap_in":
                gap = 0.0
            if worst is None or gap < worst:
                tones = " + ".join(f"{khz(t.frequency)} @ {t.amplitude:.3g} V" for t in drive.tones)
                worst, where = gap, f"program `{p.name}`, line {st.span.line}: {tones} ({state.status})"
    if skipped:
        ctx.note("ACL603", f"`{r.text}`: {skipped} step(s) whose drive the compiler chooses were not evaluated")
    if worst is None:
        return None, "", []
    return worst, "m", [f"smallest gap {worst * 1e6:.3g} um at {where}",
                        "quasi-static equilibrium (acl.analysis.mechanics.equilibrium, Eq. 1 beams)"]
