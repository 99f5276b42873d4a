"""The requests beyond the basics (issue 27): references, rename, highlights, links, folding and
selection ranges, signature help, semantic tokens, range formatting, inlay hints, pull
diagnostics, workspace symbols. Registered on :data:`acl.lsp.server.server` when it is imported.

Positions are converted at this edge: the pure functions (:mod:`acl.lsp.references`,
:mod:`acl.lsp.structure`) count code points, the client counts in the negotiated encoding.
"""
from __future__ import annotations

import os

from lsprotocol import types as T
from pygls.uris import from_fs_path

from acl.lsp.protocol import RequestFailed
from acl.lsp.server import AclLanguageServer, _no_names, _range, at, server, to_lsp

MAX_WORKSPACE_FILES = 500        # designs under the workspace folder searched by references and symbols


def _names_snap(ls: AclLanguageServer, uri: str, fresh: bool = False):
    snap = ls.snapshot(uri, fresh=fresh)
    if _no_names(snap):
        snap = ls.resolved.get(uri, snap)
    return snap


# ------------------------------------------------------------------------------------------------
# The workspace: open documents first, then the designs under the workspace folders
# ------------------------------------------------------------------------------------------------

def _workspace_files(ls: AclLanguageServer) -> list[str]:
    """The designs under the workspace folders (the rules of `acl check DIR`: no hidden, build or
    virtual folders, no links out, regular files only), at most :data:`MAX_WORKSPACE_FILES`."""
    from acl._files import designs_under
    from acl.diagnostics import DiagnosticError
    from pygls.uris import to_fs_path

    roots = []
    try:
        ws = ls.workspace
    except RuntimeError:
        return []
    for f in (ws.folders or {}).values():
        p = to_fs_path(f.uri)
        if p:
            roots.append(p)
    if not roots and ws.root_path:
        roots.append(ws.root_path)
    out: list[str] = []
    for r in roots:
        if not os.path.isdir(r):
            continue
        try:
            out.extend(designs_under(r))
        except DiagnosticError:
            continue
        if len(out) >= MAX_WORKSPACE_FILES:
            break
    return out[:MAX_WORKSPACE_FILES]


def _file_env(path: str):
    """(env, lines) of a design on disk, read under the rules of `acl check` (None if it cannot be)."""
    from acl.design.modules import Loader, read_source
    from acl.diagnostics import DiagnosticBag, DiagnosticError

    try:
        text = read_source(path)
        env = Loader(DiagnosticBag()).load_text(text, path)
    except (DiagnosticError, OSError, RecursionError):
        return None
    return env, text.split("\n")


def _documents(ls: AclLanguageServer, name: str, extra_envs=(), fresh: bool = False):
    """(uri, env, lines) of every open document, the designs of the workspace that mention ``name``,
    and ``extra_envs`` (declaring files outside the workspace)."""
    from acl.design.modules import read_source
    from acl.diagnostics import DiagnosticError

    out, seen = [], set()
    for uri in list(ls.workspace.text_documents):
        snap = _names_snap(ls, uri, fresh)
        out.append((uri, snap.env, snap.lines))
        seen.add(os.path.realpath(snap.path))
    for path in _workspace_files(ls):
        real = os.path.realpath(path)
        if real in seen:
            continue
        seen.add(real)
        try:
            if name not in read_source(path):
                continue
        except (DiagnosticError, OSError):
            continue
        got = _file_env(path)
        if got is not None:
            out.append((from_fs_path(path), *got))
    for env in extra_envs:
        if env is None or env.file.startswith("<"):
            continue
        real = os.path.realpath(env.file)
        if real not in seen:
            seen.add(real)
            out.append((from_fs_path(env.file), env, env.module.source.split("\n")))
    return out


def _target(ls: AclLanguageServer, params, fresh: bool = False):
    from acl.lsp.references import target_at

    snap = _names_snap(ls, params.text_document.uri, fresh)
    line, col = at(snap, params.position)
    return snap, target_at(snap.env, snap.lines, line, col)


def _all_references(ls, t, fresh: bool = False) -> dict[str, list[tuple[int, int, int, list[str]]]]:
    """Every occurrence of ``t`` in the open documents and the workspace (``fresh``: each open
    document's current text, as edits need; else its last checked text may answer)."""
    from acl.lsp.references import key, occurrences

    want = key(t)
    found: dict[str, list] = {}
    for uri, env, lines in _documents(ls, want[2], extra_envs=(t.env,), fresh=fresh):
        if env is None:
            continue
        for ln, a, b in occurrences(env, lines, want):
            found.setdefault(uri, []).append((ln, a, b, lines))
    return found


@server.feature(T.TEXT_DOCUMENT_REFERENCES)
def _references(ls: AclLanguageServer, params: T.ReferenceParams) -> list[T.Location] | None:
    from acl.lsp.references import declaration

    snap, got = _target(ls, params)
    if got is None:
        return None
    t = got[0]
    found = _all_references(ls, t)
    decl_file, (dl, da, db) = declaration(t)
    decl_uri = from_fs_path(os.path.abspath(decl_file)) if not decl_file.startswith("<") else decl_file
    out = []
    for uri, spots in found.items():
        for ln, a, b, lines in spots:
            if not params.context.include_declaration and _same_uri(uri, decl_uri) and (ln, a) == (dl, da):
                continue
            out.append(T.Location(uri=uri, range=_range((ln, a, ln, b), lines)))
    return out


def _same_uri(a: str, b: str) -> bool:
    from pygls.uris import to_fs_path

    pa, pb = to_fs_path(a), to_fs_path(b)
    return a == b or (pa is not None and pb is not None and os.path.realpath(pa) == os.path.realpath(pb))


def _renameable(t) -> str | None:
    """Why the declaration ``t`` cannot be renamed (None when it can)."""
    from acl.design.modules import stdlib_root

    f = os.path.realpath(t.env.file)
    if f.startswith(os.path.realpath(stdlib_root()) + os.sep):
        return f"`{t.name}` is declared in the stdlib ({os.path.basename(f)}), which a rename does not edit"
    return None


@server.feature(T.TEXT_DOCUMENT_PREPARE_RENAME)
def _prepare_rename(ls: AclLanguageServer, params: T.PrepareRenameParams):
    snap, got = _target(ls, params, fresh=True)
    if got is None:
        return None
    t, (ln, a, b) = got
    why = _renameable(t)
    if why is not None:
        raise RequestFailed(why)
    return T.PrepareRenamePlaceholder(range=_range((ln, a, ln, b), snap.lines), placeholder=snap.line(ln)[a:b])


@server.feature(T.TEXT_DOCUMENT_RENAME, T.RenameOptions(prepare_provider=True))
def _rename(ls: AclLanguageServer, params: T.RenameParams) -> T.WorkspaceEdit | None:
    from acl.lsp.document import top_level_names
    from acl.lsp.references import valid_new_name

    snap, got = _target(ls, params, fresh=True)
    if got is None:
        return None
    t = got[0]
    why = _renameable(t) or valid_new_name(params.new_name)
    if why is None and params.new_name != t.name and params.new_name in top_level_names(t.env):
        why = f"`{params.new_name}` is already declared in {os.path.basename(t.env.file)}"
    if why is not None:
        raise RequestFailed(why)
    changes = {}
    for uri, spots in _all_references(ls, t, fresh=True).items():
        changes[uri] = [T.TextEdit(range=_range((ln, a, ln, b), lines), new_text=params.new_name)
                        for ln, a, b, lines in spots]
    return T.WorkspaceEdit(changes=changes)


@server.feature(T.TEXT_DOCUMENT_DOCUMENT_HIGHLIGHT)
def _highlight(ls: AclLanguageServer, params: T.DocumentHighlightParams) -> list[T.DocumentHighlight] | None:
    from acl.lsp.references import declaration, key, occurrences

    snap, got = _target(ls, params)
    if got is None:
        return None
    t = got[0]
    decl_file, (dl, da, _) = declaration(t)
    here = os.path.realpath(decl_file) == os.path.realpath(snap.path)
    out = []
    for ln, a, b in occurrences(snap.env, snap.lines, key(t)):
        kind = T.DocumentHighlightKind.Write if here and (ln, a) == (dl, da) else T.DocumentHighlightKind.Read
        out.append(T.DocumentHighlight(range=_range((ln, a, ln, b), snap.lines), kind=kind))
    return out


# ------------------------------------------------------------------------------------------------
# Structure
# ------------------------------------------------------------------------------------------------

@server.feature(T.TEXT_DOCUMENT_DOCUMENT_LINK)
def _links(ls: AclLanguageServer, params: T.DocumentLinkParams) -> list[T.DocumentLink]:
    from acl.lsp.structure import links

    snap = _names_snap(ls, params.text_document.uri)
    return [T.DocumentLink(range=_range(r, snap.lines), target=from_fs_path(path), tooltip=path)
            for r, path in links(snap)]


@server.feature(T.TEXT_DOCUMENT_FOLDING_RANGE)
def _folding(ls: AclLanguageServer, params: T.FoldingRangeParams) -> list[T.FoldingRange]:
    from acl.lsp.structure import folding

    snap = _names_snap(ls, params.text_document.uri)
    kinds = {"comment": T.FoldingRangeKind.Comment, "imports": T.FoldingRangeKind.Imports}
    return [T.FoldingRange(start_line=a, end_line=b, kind=kinds.get(k)) for a, b, k in folding(snap)]


@server.feature(T.TEXT_DOCUMENT_SELECTION_RANGE)
def _selection(ls: AclLanguageServer, params: T.SelectionRangeParams) -> list[T.SelectionRange]:
    from acl.lsp.structure import selection

    snap = _names_snap(ls, params.text_document.uri)
    out = []
    for pos in params.positions[:1000]:
        line, col = at(snap, pos)
        node = None
        for r in reversed(selection(snap, line, col)):
            node = T.SelectionRange(range=_range(r, snap.lines), parent=node)
        out.append(node)
    return out


@server.feature(T.TEXT_DOCUMENT_SIGNATURE_HELP, T.SignatureHelpOptions(trigger_characters=["(", ","]))
def _signature(ls: AclLanguageServer, params: T.SignatureHelpParams) -> T.SignatureHelp | None:
    from acl.lsp.structure import signature

    snap = ls.snapshot(params.text_document.uri)
    got = signature(snap, *at(snap, params.position))
    if got is None:
        return None
    label, names, active, doc = got
    return T.SignatureHelp(signatures=[T.SignatureInformation(
        label=label, documentation=doc, parameters=[T.ParameterInformation(label=n) for n in names],
        active_parameter=active)], active_signature=0, active_parameter=active)


def _legend() -> T.SemanticTokensLegend:
    from acl.lsp.structure import TOKEN_MODIFIERS, TOKEN_TYPES

    return T.SemanticTokensLegend(token_types=TOKEN_TYPES, token_modifiers=TOKEN_MODIFIERS)


@server.feature(T.TEXT_DOCUMENT_SEMANTIC_TOKENS_FULL, _legend())
def _semantic(ls: AclLanguageServer, params: T.SemanticTokensParams) -> T.SemanticTokens:
    from acl.lsp.server import col_out
    from acl.lsp.structure import semantic_tokens

    snap = _names_snap(ls, params.text_document.uri)
    data: list[int] = []
    prev_line, prev_start = 0, 0
    for ln, a, n, typ, mods in semantic_tokens(snap):
        start = col_out(snap.lines, ln, a)
        length = col_out(snap.lines, ln, a + n) - start
        data += [ln - prev_line, start - prev_start if ln == prev_line else start, length, typ, mods]
        prev_line, prev_start = ln, start
    return T.SemanticTokens(data=data)


@server.feature(T.TEXT_DOCUMENT_RANGE_FORMATTING)
async def _range_formatting(ls: AclLanguageServer, params: T.DocumentRangeFormattingParams) -> list[T.TextEdit] | None:
    import asyncio

    snap = ls.snapshot(params.text_document.uri, fresh=True)
    await formatted_soon(snap)
    return await asyncio.to_thread(format_lines, snap, params.range.start.line, params.range.end.line)


async def formatted_soon(snap) -> None:
    """Wait for `acl fmt` on the snapshot's text (in the formatting process) at most
    :data:`acl.lsp.formatting.WAIT_SECONDS`; RequestFailed saying it is still running after that
    (it goes on: asked again, the request answers from its result)."""
    import asyncio

    from acl.lsp.formatting import BUSY, WAIT_SECONDS, start

    try:
        await asyncio.wait_for(asyncio.shield(asyncio.wrap_future(start(snap.text, snap.path))), WAIT_SECONDS)
    except asyncio.TimeoutError:
        raise RequestFailed(BUSY) from None


def format_lines(snap, first: int, last: int, wait: float | None = None) -> list[T.TextEdit] | None:
    """The edits of `acl fmt` that touch lines ``first``..``last`` (None: the text does not parse).
    Changed lines are replaced one by one where `acl fmt` keeps their number, so a range takes
    only its own lines; a hunk that adds or removes lines is taken whole when it touches the range."""
    from acl.lsp.formatting import hunks_of

    got = hunks_of(snap.text, snap.path, wait)
    if got is None:
        return None
    old_lines, new_lines, hunks = got
    edits = []
    for i1, i2, j1, j2 in hunks:
        if not (i1 <= last and max(i1, i2 - 1) >= first):     # a hunk that touches the range
            continue
        if i2 >= len(old_lines):          # the change reaches the end of the document
            end = (len(old_lines) - 1, len(old_lines[-1]))
            text = "\n".join(new_lines[j1:j2])
        else:
            end = (i2, 0)
            text = "".join(x + "\n" for x in new_lines[j1:j2])
        edits.append(T.TextEdit(range=_range((i1, 0, *end), old_lines), new_text=text))
    return edits


def organize_imports(snap, uri: str) -> T.CodeAction | None:
    """`source.organizeImports`: the import lines in the order `acl fmt` gives them (none while
    `acl fmt` is still running on a large design: asked again, it is there)."""
    from acl.lsp.formatting import WAIT_SECONDS, StillFormatting
    from acl.syntax import ast as A

    if snap.env is None:
        return None
    lines = [st.span.line - 1 for st in snap.env.module.statements if isinstance(st, A.Import)]
    if not lines:
        return None
    try:
        edits = format_lines(snap, min(lines), max(lines), WAIT_SECONDS)
    except StillFormatting:
        return None
    if not edits:
        return None
    return T.CodeAction(title="Organize imports (as acl fmt)", kind=T.CodeActionKind.SourceOrganizeImports,
                        edit=T.WorkspaceEdit(changes={uri: edits}))


@server.feature(T.TEXT_DOCUMENT_INLAY_HINT)
def _inlay(ls: AclLanguageServer, params: T.InlayHintParams) -> list[T.InlayHint]:
    from acl.lsp.server import col_out
    from acl.lsp.structure import inlay_hints

    snap = ls.snapshot(params.text_document.uri)
    out = []
    for ln, col, label, tip in inlay_hints(snap, params.range.start.line, params.range.end.line):
        out.append(T.InlayHint(position=T.Position(line=ln, character=col_out(snap.lines, ln, col)), label=label,
                               tooltip=tip, padding_left=False))
    return out


# ------------------------------------------------------------------------------------------------
# Pull diagnostics and workspace symbols
# ------------------------------------------------------------------------------------------------

@server.feature(T.TEXT_DOCUMENT_DIAGNOSTIC, T.DiagnosticOptions(inter_file_dependencies=True,
                                                               workspace_diagnostics=False, identifier="acl"))
def _pull_diagnostics(ls: AclLanguageServer, params: T.DocumentDiagnosticParams) -> T.FullDocumentDiagnosticReport:
    snap = ls.snapshot(params.text_document.uri)
    return T.FullDocumentDiagnosticReport(items=[to_lsp(d, snap) for d in ls.all_diagnostics(params.text_document.uri, snap)])


_SYMBOL_KIND = {"param": T.SymbolKind.Constant, "program": T.SymbolKind.Function, "capsule": T.SymbolKind.Class,
                "observe": T.SymbolKind.Event}


@server.feature(T.WORKSPACE_SYMBOL)
def _workspace_symbols(ls: AclLanguageServer, params: T.WorkspaceSymbolParams) -> list[T.SymbolInformation]:
    from acl.lsp.structure import declared_names

    query = (params.query or "").lower()
    out: list[T.SymbolInformation] = []
    for uri, env, lines in _documents(ls, ""):
        if env is None:
            continue
        for name, kind, (ln, a, b) in declared_names(env, lines):
            if query and not _fuzzy(query, name.lower()):
                continue
            out.append(T.SymbolInformation(name=name, kind=_SYMBOL_KIND.get(kind, T.SymbolKind.Struct),
                                           container_name=os.path.basename(env.file),
                                           location=T.Location(uri=uri, range=_range((ln, a, ln, b), lines))))
            if len(out) >= 1000:
                return out
    return out


def _fuzzy(query: str, name: str) -> bool:
    """Whether the letters of ``query`` appear in ``name`` in order (as editors filter)."""
    i = 0
    for ch in name:
        if i < len(query) and ch == query[i]:
            i += 1
    return i == len(query)

