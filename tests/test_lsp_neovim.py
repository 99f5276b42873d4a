"""`acl lsp` driven by Neovim's own client, headless (issue 27): the 0.7 setup of
editors/neovim/acl-nvim07.lua (Debian's Neovim is 0.7.2). Diagnostics arrive and Neovim shows them
in byte columns; hover, references and a quick fix work; the fix, applied by Neovim, gives the
right text (Neovim 0.7 sends diagnostics back in byte columns: a fix built on them gave `ddwell`)."""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("pygls", reason="acl lsp needs the optional extra acl[lsp] (pygls)")

ROOT = Path(__file__).resolve().parents[1]

DRIVE = r"""
local out = {}
vim.wait(30000, function() return #vim.diagnostic.get(0) > 0 end, 100)
for _, d in ipairs(vim.diagnostic.get(0)) do
  table.insert(out, string.format("diag %d:%d %s", d.lnum, d.col, d.code or ""))
end
local client = vim.lsp.get_active_clients()[1]
local function at(line, col)
  return {textDocument = {uri = vim.uri_from_bufnr(0)}, position = {line = line, character = col}}
end
local function req(method, params)
  local res = client.request_sync(method, params, 20000, 0)
  if res == nil then return "nil" end
  if res.err then return "error " .. vim.inspect(res.err) end
  return vim.fn.json_encode(res.result)
end
table.insert(out, "hover " .. req("textDocument/hover", at(0, 8)))
local p = at(2, 11); p.context = {includeDeclaration = true}
table.insert(out, "references " .. req("textDocument/references", p))
local ca = {textDocument = {uri = vim.uri_from_bufnr(0)},
            range = {start = {line = 1, character = 0}, ["end"] = {line = 1, character = 0}},
            context = {diagnostics = vim.lsp.diagnostic.get_line_diagnostics(0, 1)}}
local res = client.request_sync("textDocument/codeAction", ca, 20000, 0)
table.insert(out, "actions " .. #res.result)
vim.lsp.util.apply_workspace_edit(res.result[1].edit, client.offset_encoding)
table.insert(out, "applied " .. vim.api.nvim_buf_get_lines(0, 1, 2, false)[1])
vim.fn.writefile(out, vim.env.ACL_NVIM_OUT)
vim.cmd("qa!")
"""


def _nvim_headless(tmp_path: Path, init: Path, drive: str, design: Path, **extra_env) -> list[str]:
    """Run Neovim headless with ``init`` on ``design``, the Lua ``drive`` after it; the lines it wrote."""
    nvim = shutil.which("nvim")
    if nvim is None:
        pytest.skip("Neovim is not installed (Debian: apt-get install neovim)")
    (tmp_path / "drive.lua").write_text(drive, encoding="utf-8")
    out = tmp_path / "out.txt"
    bin_dir = tmp_path / "bin"                 # `acl` on PATH: this checkout's, with this Python
    bin_dir.mkdir()
    (bin_dir / "acl").write_text(f"#!/bin/sh\nexec {sys.executable} -m acl \"$@\"\n")
    (bin_dir / "acl").chmod(0o755)
    env = dict(os.environ, PATH=f"{bin_dir}{os.pathsep}{os.environ['PATH']}", ACL_NVIM_OUT=str(out),
               PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""), XDG_CONFIG_HOME=str(tmp_path),
               XDG_DATA_HOME=str(tmp_path), XDG_STATE_HOME=str(tmp_path), **extra_env)
    subprocess.run([nvim, "--headless", "-u", str(init), "-c", f"luafile {tmp_path / 'drive.lua'}", str(design)],
                   cwd=tmp_path, env=env, capture_output=True, timeout=120)
    return out.read_text(encoding="utf-8").splitlines()


def test_neovim_07_setup_drives_the_server(tmp_path):
    design = tmp_path / "t.acl"
    design.write_text("param dwell = 300 ms\nparam g2 = 5 µm * dwel\nparam g3 = dwell * 2\n", encoding="utf-8")
    got = _nvim_headless(tmp_path, ROOT / "editors" / "neovim" / "acl-nvim07.lua", DRIVE, design)
    # Neovim shows the diagnostic at byte column 19 (`µ` is 2 bytes); the server sent UTF-16 column 18
    assert got[0] == "diag 1:19 E201", got
    assert got[1].startswith("hover ") and "param dwell = 300 ms" in got[1]
    assert got[2].count('"uri"') == 2
    assert got[3] == "actions 1"
    assert got[4] == "applied param g2 = 5 µm * dwell"


# Neovim 0.10's setup (editors/neovim/acl.lua) run on Debian's 0.7 with the three calls 0.7 lacks or gates supplied by
# their 0.7 equivalents: vim.lsp.start (start_client + buf_attach_client), vim.fs.root (the markers searched upward)
# and vim.filetype.add (0.7 applies it with filetype.lua on).  The snippet's own code runs unchanged: its autocmd, its
# root markers and its command.  What 0.10's real functions do is Neovim's, not tested here.
SHIM_010 = r"""
vim.g.do_filetype_lua = 1
vim.fs = vim.fs or {}
if vim.fs.root == nil then
  vim.fs.root = function(buf, markers)
    local dir = vim.fn.fnamemodify(vim.api.nvim_buf_get_name(buf), ":p:h")
    while true do
      for _, m in ipairs(markers) do
        if vim.loop.fs_stat(dir .. "/" .. m) then return dir end
      end
      local up = vim.fn.fnamemodify(dir, ":h")
      if up == dir then return nil end
      dir = up
    end
  end
end
if vim.lsp.start == nil then
  vim.lsp.start = function(config)
    local id = vim.lsp.start_client(config)
    vim.lsp.buf_attach_client(0, id)
    return id
  end
end
dofile(vim.env.ACL_NVIM_SETUP)
"""

DRIVE_010 = r"""
local out = {}
vim.wait(30000, function() return #vim.diagnostic.get(0) > 0 end, 100)
table.insert(out, "filetype " .. vim.bo.filetype)
local client = vim.lsp.get_active_clients()[1]
table.insert(out, "client " .. (client and client.name or "none"))
table.insert(out, "root " .. (client and client.config.root_dir or "none"))
for _, d in ipairs(vim.diagnostic.get(0)) do
  table.insert(out, string.format("diag %d:%d %s", d.lnum, d.col, d.code or ""))
end
vim.fn.writefile(out, vim.env.ACL_NVIM_OUT)
vim.cmd("qa!")
"""


def test_neovim_010_setup_runs_with_its_new_calls_supplied(tmp_path):
    project = tmp_path / "project"
    (project / "designs").mkdir(parents=True)
    (project / "acl.toml").write_text("", encoding="utf-8")          # the snippet's first root marker
    design = project / "designs" / "t.acl"
    design.write_text("param dwell = 300 ms\nparam g2 = 5 um * dwel\n", encoding="utf-8")
    (tmp_path / "init.lua").write_text(SHIM_010, encoding="utf-8")
    got = _nvim_headless(tmp_path, tmp_path / "init.lua", DRIVE_010, design,
                         ACL_NVIM_SETUP=str(ROOT / "editors" / "neovim" / "acl.lua"))
    assert got[:3] == ["filetype acl", "client acl", f"root {project}"], got
    assert "diag 1:18 E201" in got[3:], got          # `dwel` at column 18: an unknown name
