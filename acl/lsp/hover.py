"""Hover: a quantity's SI value; a name's declaration; a capsule's predicted modes (frequency, Q,
phase at the program frequencies); a beam's stiffness (paper Eq. 1); a lint rule's text.

Predictions come from the same analysis functions as `acl analyze` (:mod:`acl.analysis.acoustics`,
:func:`acl.physics.beams.eq1_small_force_stiffness`); a declaration that is not part of the
document's design (a stdlib template such as ``capsules.design1``) is analysed by resolving a
one-line design that instantiates it next to the document's own imports and `use` lines.
"""
from __future__ import annotations

import functools
import math
import re

from acl.lsp.document import LINT_CODE_RE, Snapshot, Target, code_part, declaration_text, part_at, \
    resolve_name, word_at
from acl.syntax import ast as A

KIND_DOCS = {
    "capsule": "a gas-filled cavity with one or more orifices: its bubbles resonate and push (paper Fig. 1)",
    "beam": "a flexible printed beam (cantilever) whose tip carries a capsule (paper Eq. 1)",
    "spring": "a linear flexure along an axis",
    "truss": "a rigid link",
    "latch": "a bistable buckled-beam latch (paper Fig. 6)",
    "anchor": "a fixed point on the substrate",
    "medium": "the liquid the device works in (density, viscosity, sound speed, surface tension)",
    "material": "a printed material (Young's modulus, Poisson ratio, density)",
    "transducer": "the piezo transducer: band, maximum voltage and gain table",
    "effect": "a model-library effect calibrated by `acl fit` (docs/fit.md)",
    "program": "a sequence of drive steps compiled by `acl compile`",
    "param": "a named quantity; `free` marks it fittable",
}


@functools.lru_cache(maxsize=1)
def _quantity_re() -> re.Pattern:
    from acl.syntax.parser import lark_parser

    for t in lark_parser().terminals:
        if t.name == "QUANTITY":
            return re.compile(t.pattern.to_regexp())
    raise RuntimeError("grammar has no QUANTITY terminal")  # pragma: no cover


#: capsules in a design up to which a capsule's hover computes its phases and coupled modes at once;
#: beyond, the server asks its background worker (393 capsules: an eigenproblem of 1,179 bare modes)
INLINE_CAPSULES = 24
#: the program frequencies (the lowest) at which a capsule's hover gives the phase of its volume response
PHASE_FREQUENCIES = 6
#: a coupled mode is listed in a capsule's hover when its interfaces hold at least this share of the moved volume
MIN_SHARE = 0.1


def hover(snap: Snapshot, line: int, character: int, quick: bool = False) -> tuple[str, tuple[int, int, int]] | None:
    """Markdown text and (line, start, end) of the hovered word, or None.

    ``quick``: leave out what takes long on a large design (a capsule's phases and coupled modes
    with more than :data:`INLINE_CAPSULES` capsules); the text then ends with
    :data:`acl.lsp.background.PENDING_NOTE`."""
    text = snap.line(line)
    code = code_part(text)
    if character >= len(code):          # in a comment: only rule codes mean something
        w = word_at(text, character, LINT_CODE_RE)
        return (_rule_text(w[0]), (line, w[1], w[2])) if w else None
    q = word_at(code, character, _quantity_re())
    if q is not None:
        return _quantity_text(q[0]), (line, q[1], q[2])
    d = word_at(code, character, _DIRECTION)
    if d is not None and (d[1] == 0 or not (code[d[1] - 1].isalnum() or code[d[1] - 1] in "_)]")):
        return _direction_text(d[0]), (line, d[1], d[2])
    imp = _import_text(snap, line)
    if imp is not None:
        return imp, (line, 0, len(code.rstrip()))
    w = word_at(code, character)
    if w is None:
        return None
    dotted, start, end = w
    if "." not in dotted and code[end:].lstrip().startswith("("):
        from acl.lsp.structure import SIGNATURES

        if dotted in SIGNATURES:
            params, doc = SIGNATURES[dotted]
            return f"```acl\n{dotted}({', '.join(params)})\n```\n\n{doc}", (line, start, end)
    parts = dotted.split(".")
    upto = part_at(dotted, start, character) + 1
    env = snap.env
    target = resolve_name(env, parts[:upto])
    if target is None:
        if parts[0] in KIND_DOCS and upto == 1:
            return f"**{parts[0]}**: {KIND_DOCS[parts[0]]}", (line, start, end)
        key = _key_doc(snap, line, start, parts[0]) if upto == 1 else None
        return (key, (line, start, end)) if key else None
    return _target_text(snap, target, quick), (line, start, start + len(".".join(parts[:upto])))


# ------------------------------------------------------------------------------------------------

_DIRECTION = re.compile(r"[+-][xyz]\b")


def _direction_text(word: str) -> str:
    axis = "xyz".index(word[1])
    vec = ["0", "0", "0"]
    vec[axis] = "1" if word[0] == "+" else "-1"
    return (f"**direction** `{word}`: the unit vector ({', '.join(vec)}) "
            f"({'along' if word[0] == '+' else 'against'} the {word[1]} axis of the substrate frame)")


def _import_text(snap: Snapshot, line: int) -> str | None:
    """On an `import` line: the module (or declaration) it brings in, its file and what it declares."""
    env = snap.env
    if env is None:
        return None
    for st in env.module.statements:
        if isinstance(st, A.Import) and st.span.line - 1 <= line <= (st.span.end_line or st.span.line) - 1:
            alias = st.alias or (st.module[-1] if st.module else None)
            tgt = env.imports.get(alias) if alias else None
            if tgt is None:
                return None
            if isinstance(tgt, tuple):
                t = resolve_name(env, [alias])
                return _target_text(snap, t, True) if t is not None else None
            names = list(tgt.decls) + list(tgt.params) + list(tgt.programs)
            shown = ", ".join(f"`{n}`" for n in names[:20]) + (f" (+{len(names) - 20} more)" if len(names) > 20 else "")
            return (f"**import** as `{alias}`: `{tgt.file}`\n\n{len(names)} declaration(s): {shown or 'none'}")
    return None


def _quantity_text(literal: str) -> str:
    from acl.units import UnitError, describe, format_quantity, parse_unit

    m = re.match(r"(\d+\.\d+|\d+\.(?!\.)|\.\d+|\d+)([eE][+-]?\d+)?", literal)
    number = float(m.group(0))
    unit = literal[m.end():].strip()
    try:
        factor, dims = parse_unit(unit)
    except (UnitError, ValueError) as exc:
        return f"`{literal}`: unknown unit `{unit}` ({exc})"
    return f"`{literal}` = **{format_quantity(number * factor, dims)}** (SI), {describe(dims)}"


def _rule_text(code: str) -> str:
    from acl.lint.registry import load_rules

    rules = load_rules()
    r = rules.get(code)
    if r is None:
        return f"`{code}`: a check-stage diagnostic code (docs/language.md)" if code[0] in "EW" else f"`{code}`: unknown rule"
    return f"**{r.code} {r.name}** ({r.severity.value}, {r.family})\n\n{r.summary}\n\nSee docs/rules.md#{r.code.lower()}."


def _key_doc(snap: Snapshot, line: int, character: int, word: str) -> str | None:
    from acl.design.resolve import SCHEMAS
    from acl.lsp.completion import enclosing_blocks

    stack = enclosing_blocks(snap.lines, line, character)
    if not stack:
        return None
    schema = SCHEMAS.get(stack[-1])
    if not schema or word not in schema:
        return None
    k = schema[word]
    unit = f" in `{k.unit or '1'}` (any unit of that dimension)" if k.unit is not None else ""
    need = "required" if k.required else (f"optional, default {k.default!r}" if k.default is not None else "optional")
    return f"**{stack[-1]}.{word}**: {k.kind}{unit}; {need}"


def _where(target: Target) -> str:
    import os

    f = target.env.file
    node = target.node
    line = node.span.line if node is not None else 1
    return f"{os.path.basename(f)}:{line}"


def _target_text(snap: Snapshot, target: Target, quick: bool = False) -> str:
    if target.what == "module":
        decls = ", ".join(list(target.env.decls)[:12]) or "nothing"
        return f"**module** `{target.name}` ({target.env.file})\n\ndeclares: {decls}"
    node = target.node
    head = f"```acl\n{declaration_text(target.env, node)}\n```\n\n*{_where(target)}*"
    if target.what == "param":
        return head + "\n\n" + _param_value(snap, target)
    if target.what == "decl" and isinstance(node, A.Block):
        extra = ""
        try:
            if node.kind == "capsule":
                extra = _capsule_text(snap, target, quick)
            elif node.kind == "beam":
                extra = _beam_text(snap, target)
        except Exception as exc:  # a prediction that fails must not break hover
            extra = f"(prediction unavailable: {type(exc).__name__}: {exc})"
        if extra:
            return head + "\n\n" + extra
    return head


def _param_value(snap: Snapshot, target: Target) -> str:
    from acl.units import format_si

    if snap.design is not None and target.env is snap.env:
        for p in snap.design.params:
            if p.name == target.name:
                free = f"; free in {format_si(p.lower, p.unit)} .. {format_si(p.upper, p.unit)}" if p.free and p.lower is not None else ""
                return f"= **{p.value:.6g} {p.unit}**".rstrip() + f" (SI){free}"
    return "(value shown once the design resolves)"


def _instance(snap: Snapshot, target: Target, kind: str):
    """(design, element name) holding the declaration: the document's own, or a one-line instance."""
    d = snap.design
    if d is not None and target.env is snap.env:
        items = {c.name: c for c in (d.capsules if kind == "capsule" else d.beams)}
        if target.name in items:
            return d, target.name
    # a template from an import: instantiate it next to the document's imports and uses
    from acl.lsp.document import check_text

    env = snap.env
    lines = []
    for st in env.module.statements:
        if isinstance(st, (A.Import, A.Use)):
            lines.extend(snap.lines[st.span.line - 1:(st.span.end_line or st.span.line)])
    ref = _reference(env, target)
    if ref is None:
        return None, None
    # a template alone: a beam clamped at the origin, a capsule held 1 mm above the substrate
    extra = " clamp = (0, 0, 0) " if kind == "beam" else " center = (0, 0, 1 mm) "
    lines.append(f"{kind} __hover like {ref} {{{extra}}}")
    inst = check_text("\n".join(lines) + "\n", snap.path)
    if inst.design is None:
        return None, None
    return inst.design, "__hover"


def _reference(env, target: Target) -> str | None:
    """How the document names ``target`` (``alias.name``)."""
    for alias, tgt in env.imports.items():
        if isinstance(tgt, tuple):
            if tgt[0] is target.env and tgt[1] == target.name:
                return alias
        elif tgt is target.env:
            return f"{alias}.{target.name}"
    return None


def _capsule_text(snap: Snapshot, target: Target, quick: bool = False) -> str:
    from acl.analysis import acoustics as AC
    from acl.analysis.report import program_frequencies

    design, name = _instance(snap, target, "capsule")
    if design is None:
        return "(predictions shown once the design resolves)"
    cap = design.capsule(name)
    alone = " (the template alone, 1 mm above the substrate)" if name == "__hover" else ""
    modes = AC.capsule_modes(design, cap)
    rows = ["| mode | f (kHz) | Q | dominant orifice |", "|---|---|---|---|"]
    for i, m in enumerate(modes):
        q = f"{m.q:.1f}" + (" (declared)" if m.q_declared else "")
        rows.append(f"| {i + 1} | {m.frequency_hz / 1e3:.1f} | {q} | {m.dominant_orifice} ({m.share:.0%}) |")
    out = f"**predicted modes**{alone} (as `acl analyze`):\n\n" + "\n".join(rows)
    if quick and len(design.capsules) > INLINE_CAPSULES:
        from acl.lsp.background import PENDING_NOTE

        return out + "\n\nphases and coupled modes: " + PENDING_NOTE
    freqs = program_frequencies(snap.design) if snap.design is not None else []
    if freqs:
        import numpy as np

        shown = freqs[:PHASE_FREQUENCIES]          # (each frequency is solved alone: the others are not needed)
        resp = AC.orifice_response(design, cap, shown)
        k = [o.name for o in cap.orifices].index(modes[0].dominant_orifice) if modes else 0
        ph = ", ".join(f"{f / 1e3:g} kHz: {math.degrees(float(np.angle(resp[j, k]))):.0f} deg"
                       for j, f in enumerate(shown))
        out += f"\n\nphase of `{cap.orifices[k].name}` volume vs drive: {ph}"
    if name != "__hover" and len(design.capsules) > 1:
        mine = AC.coupled_modes_of(design, cap, MIN_SHARE)      # = coupled_modes(design) filtered by share
        if mine:
            rows = ["| coupled mode | f (kHz) | Q | interfaces: share (phase) |", "|---|---|---|---|"]
            for i, m in enumerate(mine[:6]):
                parts = ", ".join(f"{k} {v:.0%} ({m.phases.get(k, 0.0):.0f} deg)" for k, v in m.shares.items() if v >= 0.05)
                rows.append(f"| {i + 1} | {m.frequency_hz / 1e3:.1f} | {m.q:.1f} | {parts} |")
            out += "\n\n**with its neighbours** (all bubbles as one system):\n\n" + "\n".join(rows)
    notes = modes[0].notes if modes else ()
    if notes:
        out += "\n\n" + "\n".join(f"note: {n}" for n in notes)
    return out


def _beam_text(snap: Snapshot, target: Target) -> str:
    from acl.physics.beams import eq1_small_force_stiffness
    from acl.units import format_si

    design, name = _instance(snap, target, "beam")
    if design is None:
        return "(stiffness shown once the design resolves)"
    b = design.beam(name)
    EI = b.bending_stiffness
    k = eq1_small_force_stiffness(b.length, b.rigid_length, EI)
    return (f"**stiffness** k = {k:.4g} N/m at the tip (paper Eq. 1, small force; L = {format_si(b.length, 'm')}, "
            f"l = {format_si(b.rigid_length, 'm')}, EI = {EI:.3g} N*m^2)")
