"""Document symbols (the outline): imports, params, declarations with their nested blocks, mounts
omitted, observations, programs with their steps."""
from __future__ import annotations

from acl.lsp.document import Snapshot, name_position
from acl.syntax import ast as A

# LSP SymbolKind numbers (lsprotocol.types.SymbolKind)
_KIND = {"module": 2, "capsule": 5, "beam": 23, "spring": 23, "truss": 23, "latch": 23, "anchor": 20,
         "medium": 19, "material": 19, "transducer": 19, "effect": 7, "param": 14, "program": 12,
         "observe": 7, "step": 24, "block": 19}


def outline(snap: Snapshot) -> list[dict]:
    """Nested symbols: dicts with name, detail, kind (SymbolKind number), range, selection, children.

    Ranges are (line, character, end_line, end_character), 0-based.
    """
    if snap.env is None:
        return []
    lines = snap.lines
    out = []
    for st in snap.env.module.statements:
        if isinstance(st, A.Import):
            name = st.alias or (".".join(st.module) if st.module else st.file)
            out.append(_sym(lines, name, "import", _KIND["module"], st.span, st.alias or (st.module[-1] if st.module else None)))
        elif isinstance(st, A.ParamDecl):
            out.append(_sym(lines, st.name, "param" + (" (free)" if st.free else ""), _KIND["param"], st.span, st.name))
        elif isinstance(st, A.Block):
            out.append(_block(lines, st))
        elif isinstance(st, A.ObserveDecl):
            out.append(_sym(lines, st.name, f"observe {st.call.name}", _KIND["observe"], st.span, st.name))
        elif isinstance(st, A.ProgramDecl):
            s = _sym(lines, st.name, "program", _KIND["program"], st.span, st.name)
            for i, step in enumerate(st.steps):
                word = type(step).__name__[:-1].lower()
                s["children"].append(_sym(lines, f"{i + 1}. {word}", lines[step.span.line - 1].strip()[:60],
                                          _KIND["step"], step.span, None))
            out.append(s)
    return out


def _block(lines, blk: A.Block) -> dict:
    name = blk.name or blk.kind
    detail = blk.kind + (f" like {blk.like.dotted}" if blk.like is not None else "")
    s = _sym(lines, name, detail, _KIND.get(blk.kind, _KIND["block"]), blk.span, blk.name, blk.kind_span)
    for sub in blk.blocks():
        s["children"].append(_block(lines, sub))
    return s


def _sym(lines, name, detail, kind, span, word, fallback=None) -> dict:
    end_line = (span.end_line or span.line) - 1
    end_col = (span.end_column or span.column + 1) - 1
    if word:
        ln, a, b = name_position(lines, span, word)
    else:
        f = fallback or span
        ln, a, b = f.line - 1, f.column - 1, (f.end_column or f.column + 1) - 1 if (f.end_line or f.line) == f.line else f.column
    rng = (span.line - 1, span.column - 1, end_line, end_col)
    sel = (ln, a, ln, b)
    if not (rng[:2] <= sel[:2] and sel[2:] <= rng[2:]):
        sel = (rng[0], rng[1], rng[0], rng[1])
    return {"name": name, "detail": detail, "kind": kind, "range": rng, "selection": sel, "children": []}
