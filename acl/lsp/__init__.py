"""`acl lsp`: a language server over stdio (needs the optional extra ``acl[lsp]``: pygls, lsprotocol).

A thin protocol layer (:mod:`acl.lsp.server`) over the parser, resolver and diagnostics of
`acl check` (:mod:`acl.lsp.document`) and the rules of `acl lint` (:mod:`acl.lsp.lint`), with one
module per feature: :mod:`~acl.lsp.hover`, :mod:`~acl.lsp.definition`, :mod:`~acl.lsp.completion`,
:mod:`~acl.lsp.symbols`, :mod:`~acl.lsp.actions` (quick fixes for "did you mean" hints) and
:mod:`~acl.lsp.formatting` (through `acl fmt`).  Only the server module imports pygls.
"""
