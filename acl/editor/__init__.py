"""Editor support that needs no server: syntax highlighting (a Pygments lexer).

The TextMate grammar for VS Code and other editors lives in ``editors/vscode/``; the language
server is ``acl lsp``. Both highlighters follow the grammar's terminals (acl/syntax/grammar.lark);
tests/test_highlighting.py checks them against the parser's own tokens on every example.
"""
