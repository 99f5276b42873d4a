-- acl in Neovim 0.7 to 0.9 (put in init.lua, or `:luafile` it). Neovim 0.10+: see acl.lua.
-- 0.7 has no vim.lsp.start (0.8) nor vim.fs.root (0.10): one client per project root, started
-- with vim.lsp.start_client and attached to each .acl buffer. The root is the nearest folder
-- holding acl.toml, else the file's folder. `acl` must be on PATH (pip install '.[lsp]' in a clone of acl).
vim.api.nvim_create_autocmd({ "BufRead", "BufNewFile" }, { pattern = "*.acl", command = "setfiletype acl" })
vim.api.nvim_create_autocmd("FileType", {
  pattern = "acl",
  callback = function(args)
    local file = vim.api.nvim_buf_get_name(args.buf)
    local folder = vim.fn.fnamemodify(file, ":p:h")
    local marker = vim.fn.findfile("acl.toml", folder .. ";")
    local root = marker ~= "" and vim.fn.fnamemodify(marker, ":p:h") or folder
    _G.acl_lsp_clients = _G.acl_lsp_clients or {}
    local id = _G.acl_lsp_clients[root]
    if id == nil then
      id = vim.lsp.start_client({ name = "acl", cmd = { "acl", "lsp" }, root_dir = root })
      _G.acl_lsp_clients[root] = id
    end
    vim.lsp.buf_attach_client(args.buf, id)
  end,
})
