"""Every request of `acl lsp` driven through Neovim's own client, headless (issue 27): Neovim 0.7
(Debian's) with the setup of editors/neovim/acl-nvim07.lua opens tests/test_lsp_features.py's
design and asks each request the server answers; each answer is checked for its content, in the
positions Neovim counts (UTF-16, the 0.7 client's encoding).  The run-from-editor commands
(`acl.analyze`, `acl.compile`, `acl.lint`) are checked with the `$/progress` Neovim receives, and a
long compile is cancelled with Neovim's own `cancel_request`."""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("pygls", reason="acl lsp needs the optional extra acl[lsp] (pygls)")

from test_lsp_features import LIB, MAIN  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
TEXT = MAIN + "param   messy=1 um\n"          # one line for formatting to change
L = TEXT.split("\n")


def _at(needle: str, word: str) -> tuple[int, int]:
    ln = next(i for i, x in enumerate(L) if needle in x)
    return ln, L[ln].index(word)


DRIVE = r"""
local out = {}
local client
vim.wait(30000, function()
  client = vim.lsp.get_active_clients()[1]
  return client ~= nil and client.initialized
end, 50)
local buf = vim.api.nvim_get_current_buf()
local uri = vim.uri_from_bufnr(buf)
local doc = {uri = uri}
-- every $/progress as Neovim's client receives it (0.7 answers window/workDoneProgress/create itself)
local progress = {}
local shown_progress = vim.lsp.handlers["$/progress"]
vim.lsp.handlers["$/progress"] = function(err, result, ctx, config)
  table.insert(progress, result)
  if shown_progress then return shown_progress(err, result, ctx, config) end
end
local cases = vim.fn.json_decode(vim.fn.readfile(vim.env.ACL_NVIM_CASES)[1])
for _, case in ipairs(cases) do
  local params = case.params
  if params.textDocument and params.textDocument.uri == "?" then params.textDocument = doc end
  if case.item_from then params = out[case.item_from].first end
  local res = client.request_sync(case.method, params, 20000, buf)
  local rec = {method = case.method}
  if res == nil then rec.error = "no reply (timeout)"
  elseif res.err then rec.error = res.err.message or vim.inspect(res.err)
  else
    rec.result = res.result
    if type(res.result) == "table" then
      rec.first = res.result[1] or (res.result.items and res.result.items[1]) or vim.NIL
    end
  end
  out[case.name] = rec
end
-- a long compile (the Fig. 3 circles) started, then cancelled with the client's own cancel_request
vim.cmd("edit " .. vim.fn.fnameescape(vim.env.ACL_NVIM_SLOW))
local slow = vim.api.nvim_get_current_buf()
vim.wait(30000, function() return vim.lsp.buf_is_attached(slow, client.id) end, 20)
local seen = #progress
local ok, rid = client.request("workspace/executeCommand",
  {command = "acl.compile", arguments = {vim.uri_from_bufnr(slow), "circle"}}, function() end, slow)
local begin
vim.wait(60000, function()
  for i = seen + 1, #progress do
    local p = progress[i]
    if p.value.kind == "begin" and p.value.title == "acl compile" then begin = p return true end
  end
  return false
end, 5)
local stop = {requested = ok}
if begin then
  client.cancel_request(rid)
  vim.wait(60000, function()
    for _, p in ipairs(progress) do
      if p.token == begin.token and p.value.kind == "end" then stop.end_message = p.value.message return true end
    end
    return false
  end, 20)
  stop.cancellable = begin.value.cancellable
end
out.cancel = stop
out.progress = progress
vim.fn.writefile({vim.fn.json_encode(out)}, vim.env.ACL_NVIM_OUT)
vim.cmd("qa!")
"""


def _cases() -> list[dict]:
    doc = {"textDocument": {"uri": "?"}}

    def at(name, method, needle, word, shift=0, **extra):
        ln, ch = _at(needle, word)
        return {"name": name, "method": method,
                "params": {**doc, "position": {"line": ln, "character": ch + shift}, **extra}}

    dwell = ("param dwell", "dwell")
    whole = {"start": {"line": 0, "character": 0}, "end": {"line": len(L), "character": 0}}
    messy = _at("param   messy", "param")[0]
    return [
        at("hover", "textDocument/hover", *dwell),
        at("definition", "textDocument/definition", "param w", "gap"),
        at("completion", "textDocument/completion", "observe tip", "arm", 1),
        {"name": "completion_resolve", "method": "completionItem/resolve", "params": {}, "item_from": "completion"},
        at("references", "textDocument/references", *dwell, context={"includeDeclaration": True}),
        at("prepareRename", "textDocument/prepareRename", *dwell),
        at("rename", "textDocument/rename", *dwell, newName="wait_time"),
        at("highlight", "textDocument/documentHighlight", *dwell),
        at("signature", "textDocument/signatureHelp", "observe tip", "+x"),
        {"name": "symbols", "method": "textDocument/documentSymbol", "params": {**doc}},
        {"name": "links", "method": "textDocument/documentLink", "params": {**doc}},
        {"name": "folding", "method": "textDocument/foldingRange", "params": {**doc}},
        {"name": "selection", "method": "textDocument/selectionRange",
         "params": {**doc, "positions": [{"line": _at(*dwell)[0], "character": 7}]}},
        {"name": "tokens", "method": "textDocument/semanticTokens/full", "params": {**doc}},
        {"name": "inlay", "method": "textDocument/inlayHint", "params": {**doc, "range": whole}},
        {"name": "lenses", "method": "textDocument/codeLens", "params": {**doc}},
        {"name": "lens_resolve", "method": "codeLens/resolve", "params": {}, "item_from": "lenses"},
        {"name": "organize", "method": "textDocument/codeAction",
         "params": {**doc, "range": whole, "context": {"diagnostics": [], "only": ["source.organizeImports"]}}},
        {"name": "formatting", "method": "textDocument/formatting",
         "params": {**doc, "options": {"tabSize": 2, "insertSpaces": True}}},
        {"name": "range_formatting", "method": "textDocument/rangeFormatting",
         "params": {**doc, "options": {"tabSize": 2, "insertSpaces": True},
                    "range": {"start": {"line": messy, "character": 0}, "end": {"line": messy + 1, "character": 0}}}},
        {"name": "pull", "method": "textDocument/diagnostic", "params": {**doc}},
        {"name": "workspace_symbol", "method": "workspace/symbol", "params": {"query": "c1"}},
        {"name": "command", "method": "workspace/executeCommand", "params": {"command": "acl.lint", "arguments": ["?"]}},
        {"name": "command_analyze", "method": "workspace/executeCommand",
         "params": {"command": "acl.analyze", "arguments": ["?"]}},
        {"name": "command_compile", "method": "workspace/executeCommand",
         "params": {"command": "acl.compile", "arguments": ["?", "ramp"]}},
        at("hover_unopened", "textDocument/hover", *dwell),
    ]


def test_every_request_through_neovim_07(tmp_path):
    nvim = shutil.which("nvim")
    if nvim is None:
        pytest.skip("Neovim is not installed (Debian: apt-get install neovim)")
    (tmp_path / "lib.acl").write_text(LIB, encoding="utf-8")
    design = tmp_path / "main.acl"
    design.write_text(TEXT, encoding="utf-8")
    cases = _cases()
    slow = tmp_path / "slow.acl"       # a compile long enough to be cancelled: the Fig. 3 circles
    slow.write_text((ROOT / "examples" / "fig3_three_orifice.acl").read_text(encoding="utf-8"), encoding="utf-8")
    for c in cases:                # the commands' argument is the document; the last hover names a file never opened
        if c["name"].startswith("command"):
            c["params"]["arguments"] = [design.as_uri() if a == "?" else a for a in c["params"]["arguments"]]
        if c["name"] == "hover_unopened":
            c["params"]["textDocument"] = {"uri": (tmp_path / "lib.acl").as_uri()}
    (tmp_path / "cases.json").write_text(json.dumps(cases), encoding="utf-8")
    (tmp_path / "drive.lua").write_text(DRIVE, encoding="utf-8")
    out = tmp_path / "out.json"
    bin_dir = tmp_path / "bin"                 # `acl` on PATH: this checkout's, with this Python
    bin_dir.mkdir()
    (bin_dir / "acl").write_text(f"#!/bin/sh\nexec {sys.executable} -m acl \"$@\"\n")
    (bin_dir / "acl").chmod(0o755)
    env = dict(os.environ, PATH=f"{bin_dir}{os.pathsep}{os.environ['PATH']}", ACL_NVIM_OUT=str(out),
               ACL_NVIM_CASES=str(tmp_path / "cases.json"), ACL_NVIM_SLOW=str(slow),
               PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""), XDG_CONFIG_HOME=str(tmp_path),
               XDG_DATA_HOME=str(tmp_path), XDG_STATE_HOME=str(tmp_path))
    subprocess.run([nvim, "--headless", "-u", str(ROOT / "editors" / "neovim" / "acl-nvim07.lua"),
                    "-c", f"luafile {tmp_path / 'drive.lua'}", str(design)], cwd=tmp_path, env=env,
                   capture_output=True, timeout=180)
    got = json.loads(out.read_text(encoding="utf-8"))
    assert set(got) == {c["name"] for c in cases} | {"cancel", "progress"}
    for name, rec in got.items():
        if name not in ("hover_unopened", "cancel", "progress"):
            assert "error" not in rec, (name, rec)

    def res(name):
        return got[name]["result"]

    assert "300 ms" in res("hover")["contents"]["value"]
    assert res("definition")["uri"].endswith("/lib.acl") and res("definition")["range"]["start"]["line"] == 2
    labels = {i["label"] for i in res("completion")["items"]}
    assert "arm" in labels
    assert res("completion_resolve").get("documentation")
    dl = _at("param dwell", "dwell")[0]
    assert sorted(r["range"]["start"]["line"] for r in res("references")) == [dl, _at("drive 125", "dwell")[0],
                                                                             _at("pause dwell", "dwell")[0]]
    assert res("prepareRename")["placeholder"] == "dwell"
    edits = next(iter(res("rename")["changes"].values()))
    assert len(edits) == 3 and {e["newText"] for e in edits} == {"wait_time"}
    assert len(res("highlight")) == 3
    assert "displacement" in res("signature")["signatures"][0]["label"]
    names = {s["name"] for s in res("symbols")}
    assert {"dwell", "arm", "c1", "ramp", "tip"} <= names
    assert any(x["target"].endswith("/lib.acl") for x in res("links"))
    assert res("folding") and res("selection")[0]["range"]["start"]["line"] == dl
    assert len(res("tokens")["data"]) % 5 == 0 and len(res("tokens")["data"]) >= 5 * 20
    assert any("s" in str(h["label"]) for h in res("inlay"))
    lens_titles = [x.get("command", {}).get("title", "") for x in res("lenses")]
    assert any("compile ramp" in t for t in lens_titles)
    assert res("lens_resolve")["command"]["title"].startswith("modes: ")
    messy = _at("param   messy", "param")[0]
    assert res("organize") and res("organize")[0]["kind"] == "source.organizeImports"
    (edits,) = res("organize")[0]["edit"]["changes"].values()       # applied: the imports sorted as acl fmt
    lines = TEXT.split("\n")
    for e in sorted(edits, key=lambda e: e["range"]["start"]["line"], reverse=True):
        lines[e["range"]["start"]["line"]:e["range"]["end"]["line"]] = e["newText"].split("\n")[:-1]
    assert lines[:5] == ["import stdlib.beams", "import stdlib.capsules", "import stdlib.media",
                         "import stdlib.transducers", 'import "lib.acl" as lib'] and lines[5:] == L[5:]
    assert res("formatting") and "param messy = 1 um" in res("formatting")[0]["newText"]
    (edit,) = res("range_formatting")       # the line, and the blank line acl fmt puts after a program
    assert edit["range"]["start"]["line"] == messy and "param messy = 1 um" in edit["newText"]
    assert res("pull")["kind"] == "full"
    assert any(s["name"] == "c1" for s in res("workspace_symbol"))
    assert "lint" in str(res("command"))
    # the run-from-editor commands, each with its $/progress (begin, then end with the summary)
    assert res("command_analyze").startswith("acl analyze: 1 capsule(s): c1 12"), res("command_analyze")
    assert res("command_compile").startswith("acl compile ramp: ") and "segment(s)" in res("command_compile")
    ends = {p["value"]["message"] for p in got["progress"] if p["value"].get("kind") == "end"}
    titles = {p["value"].get("title") for p in got["progress"] if p["value"].get("kind") == "begin"}
    assert {"acl lint", "acl analyze", "acl compile"} <= titles, titles
    assert res("command_analyze") in ends and res("command_compile") in ends
    # cancelled from Neovim (client.cancel_request): the work stops and its progress says so
    assert got["cancel"]["requested"] and got["cancel"].get("cancellable") is True, got["cancel"]
    assert got["cancel"].get("end_message") == "acl compile: cancelled by the client", got["cancel"]
    assert "not open" in got["hover_unopened"]["error"] and "Traceback" not in got["hover_unopened"]["error"]
