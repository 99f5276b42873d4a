-- acl in Neovim 0.10+ (put in init.lua). Neovim 0.7 to 0.9: see acl-nvim07.lua.
vim.filetype.add({ extension = { acl = "acl" } })
vim.api.nvim_create_autocmd("FileType", {
  pattern = "acl",
  callback = function(args)
    vim.lsp.start({
      name = "acl",
      cmd = { "acl", "lsp" },
      root_dir = vim.fs.root(args.buf, { "acl.toml", "pyproject.toml", ".git" }),
    })
  end,
})
