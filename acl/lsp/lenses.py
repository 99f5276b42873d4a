"""Running acl from the editor: code lenses and commands.

Lenses: over each capsule its predicted modes (resolved lazily, one capsule at a time, as the
editor shows them: ``codeLens/resolve``), over each program "compile", over each `require` its
value and whether it passes (computed by the background worker: requirements need the whole
analysis). Commands (``workspace/executeCommand``): ``acl.analyze``, ``acl.compile``,
``acl.lint`` on an open document; each runs in the worker, reports ``$/progress`` when the client
offers a token, shows its summary (``window/showMessage``) and returns it. A newer edit of the
document cancels a command still running on the older text; so does the client, with
``$/cancelRequest`` or the progress's cancel (``window/workDoneProgress/cancel``): the worker
stops the job.
"""
from __future__ import annotations

import asyncio
import itertools

from lsprotocol import types as T

from acl.lsp.protocol import RequestFailed
from acl.lsp.server import AclLanguageServer, _range, server
from acl.syntax import ast as A

COMMANDS = ("acl.analyze", "acl.compile", "acl.lint")
_RUNS = itertools.count(1)


@server.feature(T.TEXT_DOCUMENT_CODE_LENS, T.CodeLensOptions(resolve_provider=True))
def _code_lens(ls: AclLanguageServer, params: T.CodeLensParams) -> list[T.CodeLens]:
    from acl.lsp.background import requirement_values, text_key

    uri = params.text_document.uri
    snap = ls.snapshot(uri)
    if snap.env is None:
        return []
    out = []
    reqs = None
    if snap.design is not None and any(isinstance(st, A.RequireDecl) for st in snap.env.module.statements):
        reqs = ls.in_background((uri, text_key(snap.text), "requires"), "acl: requirements", requirement_values,
                                snap.path, snap.text)
    by_line = {r["line"]: r for r in reqs or [] if isinstance(reqs, list)}
    for st in snap.env.module.statements:
        ln = st.span.line - 1
        rng = _range((ln, 0, ln, 0), snap.lines)
        if isinstance(st, A.Block) and st.kind == "capsule" and st.name and snap.design is not None:
            out.append(T.CodeLens(range=rng, data={"uri": uri, "capsule": st.name, "version": snap.version}))
        elif isinstance(st, A.ProgramDecl):
            out.append(T.CodeLens(range=rng, command=T.Command(title=f"▶ compile {st.name}", command="acl.compile",
                                                               arguments=[uri, st.name])))
        elif isinstance(st, A.RequireDecl) and snap.design is not None:
            r = by_line.get(st.span.line)
            if r is None:
                title = "require: computing…" if reqs is None else "require: not evaluated"
            else:
                title = ("✓ pass" if r["ok"] else "✗ fail") + f": {_value(r)} ({r['detail']})"
            out.append(T.CodeLens(range=rng, command=T.Command(title=title, command="acl.analyze", arguments=[uri])))
    return out


def _value(r: dict) -> str:
    from acl.units import format_si

    return "no value" if r["value"] is None else format_si(r["value"], r["unit"])


@server.feature(T.CODE_LENS_RESOLVE)
def _resolve_lens(ls: AclLanguageServer, lens: T.CodeLens) -> T.CodeLens:
    data = lens.data if isinstance(lens.data, dict) else {}
    uri, name = data.get("uri"), data.get("capsule")
    title = "modes: unavailable"
    if isinstance(uri, str) and isinstance(name, str) and ls.is_open(uri):
        snap = ls.snapshot(uri)
        cap = {c.name: c for c in snap.design.capsules}.get(name) if snap.design is not None else None
        if cap is not None:
            from acl.analysis import acoustics as AC

            modes = AC.capsule_modes(snap.design, cap)
            title = "modes: " + (", ".join(f"{m.frequency_hz / 1e3:.1f} kHz (Q {m.q:.1f})" for m in modes[:4])
                                 or "none in band")
    lens.command = T.Command(title=title, command="acl.analyze", arguments=[uri])
    return lens


# ------------------------------------------------------------------------------------------------
# Commands, run in the worker
# ------------------------------------------------------------------------------------------------

def analyze_summary(path: str, text: str) -> str:
    """`acl analyze` in a few lines: each capsule's first mode, the requirements."""
    from acl.analysis.report import analyze
    from acl.lsp.background import checked

    snap = checked(path, text)
    if snap.design is None:
        errors = [d for d in snap.diagnostics if d.severity.value == "error"]
        return f"acl analyze: the design has {len(errors)} error(s); fix them first"
    rep = analyze(snap.design)
    caps = ", ".join(f"{c['name']} {c['modes'][0]['frequency_hz'] / 1e3:.1f} kHz" for c in rep.capsules[:8]
                     if c["modes"])
    more = f" (+{len(rep.capsules) - 8} more)" if len(rep.capsules) > 8 else ""
    req = f"; requirements: {sum(r['ok'] for r in rep.requires)}/{len(rep.requires)} pass" if rep.requires else ""
    return f"acl analyze: {len(rep.capsules)} capsule(s): {caps or 'none'}{more}{req}"


def compile_summary(path: str, text: str, program: str | None) -> str:
    """`acl compile` without writing files: segments, duration, peak voltage, goals."""
    from acl.diagnostics import DiagnosticError
    from acl.lsp.background import checked
    from acl.schedule.compile import compile_program

    snap = checked(path, text)
    if snap.design is None:
        return "acl compile: the design has errors; fix them first"
    names = [p.name for p in snap.design.programs]
    if program is None:
        if len(names) != 1:
            return f"acl compile: name a program ({', '.join(names) or 'none declared'})"
        program = names[0]
    if program not in names:
        return f"acl compile: no program `{program}` ({', '.join(names) or 'none declared'})"
    try:
        s = compile_program(snap.design, program)
    except DiagnosticError as exc:
        d = exc.diagnostics[0]
        return f"acl compile {program}: {d.severity.value}[{d.code}] at {d.location()}: {d.message}"
    end = max((seg.end_s for seg in s.segments), default=0.0)
    peak = max((seg.peak_v or 0.0 for seg in s.segments), default=0.0)
    return (f"acl compile {program}: {len(s.segments)} segment(s), {end:.4g} s, peak {peak:.3g} V "
            f"(limit {s.max_voltage_v:.3g} V), {len(s.goals)} goal(s)")


def lint_summary(path: str, text: str) -> str:
    from acl.lsp.lint import lint_text

    found = lint_text(path, text)
    codes = sorted({d.code for d in found})
    return f"acl lint: {len(found)} finding(s)" + (f": {', '.join(codes[:10])}" if codes else "")


@server.command("acl.analyze")
async def _cmd_analyze(ls: AclLanguageServer, *args):
    return await _run(ls, args, "analyze", analyze_summary)


@server.command("acl.compile")
async def _cmd_compile(ls: AclLanguageServer, *args):
    return await _run(ls, args, "compile", compile_summary)


@server.command("acl.lint")
async def _cmd_lint(ls: AclLanguageServer, *args):
    return await _run(ls, args, "lint", lint_summary)


async def _run(ls: AclLanguageServer, args, what: str, fn) -> str:
    from acl.lsp.background import text_key

    uri = args[0] if args and isinstance(args[0], str) else None
    if uri is None:
        raise RequestFailed(f"acl.{what}: the first argument is the URI of an open document")
    snap = ls.snapshot(uri)
    extra = (args[1] if len(args) > 1 and isinstance(args[1], str) else None,) if what == "compile" else ()
    key = (uri, text_key(snap.text), what, *extra)
    token = f"acl-{what}-{key[1][:12]}-{next(_RUNS)}"      # one token per run: pygls refuses a token twice
    stopped: list[str] = []         # why the client stopped the work

    def stop(why: str) -> None:
        if not stopped:
            stopped.append(why)
            ls.worker.cancel(key)

    progress = False
    caps = getattr(ls.client_capabilities, "window", None)
    if caps is not None and getattr(caps, "work_done_progress", False):
        try:
            await asyncio.wait_for(ls.work_done_progress.create_async(token), timeout=2)
            progress = True
        except Exception:          # the client refused or did not answer: run without
            pass
    if progress:
        loop = asyncio.get_running_loop()
        ls.work_done_progress.begin(token, T.WorkDoneProgressBegin(title=f"acl {what}", message=snap.path,
                                                                   cancellable=True))
        asked = ls.work_done_progress.tokens.get(token)     # cancelled by window/workDoneProgress/cancel
        if asked is not None:
            asked.add_done_callback(lambda f: loop.call_soon_threadsafe(stop, "cancelled in the editor")
                                    if f.cancelled() else None)
    try:
        result = ls.worker.get(key, fn, snap.path, snap.text, *extra)
        if result is None:
            fut = ls.worker.future(key)
            if fut is not None:
                try:
                    await asyncio.wrap_future(fut)
                except asyncio.CancelledError:
                    if asyncio.current_task().cancelling():    # $/cancelRequest: this task, not the job
                        raise
                except Exception:      # stopped by a newer edit or by the client, or a worker that died
                    pass
            result = ls.worker.peek(key) or f"acl {what}: {stopped[0] if stopped else 'cancelled (the document changed)'}"
    except asyncio.CancelledError:
        stop("cancelled by the client")
        if progress:
            ls.work_done_progress.end(token, T.WorkDoneProgressEnd(message=f"acl {what}: {stopped[0]}"))
            ls.work_done_progress.tokens.pop(token, None)
        raise
    if progress:
        ls.work_done_progress.end(token, T.WorkDoneProgressEnd(message=str(result)[:200]))
        ls.work_done_progress.tokens.pop(token, None)
    ls.window_show_message(T.ShowMessageParams(type=T.MessageType.Info, message=str(result)))
    return result
