"""A Pygments lexer for acl, registered as the ``pygments.lexers`` entry point ``acl``.

    from pygments.lexers import get_lexer_by_name
    lexer = get_lexer_by_name("acl")

Token classes: keywords ``Keyword`` (imports ``Keyword.Namespace``, declaration kinds
``Keyword.Declaration``), units ``Keyword.Type`` (as Pygments' CSS lexer colours units),
numbers ``Number.Integer``/``Number.Float`` (``2e-5`` is a float), strings ``String.Double``,
comments ``Comment.Single`` (suppressions ``# acl: ignore[...]`` are ``Comment.Special``),
directions ``Name.Constant``, calls ``Name.Function``, declared names ``Name.Class``,
parameters ``Name.Variable``, keys ``Name.Attribute``. The number and unit patterns are the
grammar's QUANTITY/NUMBER terminals, so `5 in` is a number and the keyword `in`.
"""
from __future__ import annotations

from pygments.lexer import RegexLexer, bygroups, words
from pygments.token import Comment, Keyword, Name, Number, Operator, Punctuation, String, Text, Whitespace

__all__ = ["AclLexer"]

# Declaration kinds (acl.design.resolve.DECL_KINDS) and the blocks nested in them.
KINDS = ("medium", "material", "transducer", "generator", "amplifier", "capsule", "beam", "spring", "truss", "latch",
         "anchor", "effect", "cavity", "orifice")
# Every keyword of the grammar: statements, program steps and the words that join their parts.
KEYWORDS = ("param", "use", "mount", "fix", "link", "observe", "require", "program", "drive", "sweep", "pause",
            "follow", "switch", "hold", "cross", "on", "to", "with", "for", "in", "at", "along", "above", "phase",
            "free", "like", "limit", "slew", "margin", "using", "log", "uncertainty")
# Words that can never start a unit (the grammar's QUANTITY look-ahead); nor can an exponent
# (`2 e5` is a number and a name, `2e5` a number).
NOT_UNITS = ("for", "in", "to", "at", "on", "with", "free", "limit", "slew", "margin", "using", "along", "above",
             "phase", "like", "as", "log")

_U0 = "A-Za-z\u00b5\u03bc\u00b0\u2126%"
_U1 = "A-Za-z0-9\u00b5\u03bc\u00b0\u2126%"
UNIT = rf"(?![eE][+-]?\d)(?!(?:{'|'.join(NOT_UNITS)})\b)[{_U0}][{_U1}]*(?:\^-?\d+)?(?:[*/\u00b7][{_U0}][{_U1}]*(?:\^-?\d+)?)*"
FLOAT = r"(?:\d+\.\d+|\d+\.(?!\.)|\.\d+)(?:[eE][+-]?\d+)?|\d+[eE][+-]?\d+"
INTEGER = r"\d+"
NAME = r"[A-Za-z_][A-Za-z0-9_]*"
_KIND = rf"\b({'|'.join(KINDS)})\b"


class AclLexer(RegexLexer):
    """acl design files (acoustically programmable soft micro-mechanisms)."""

    name = "acl"
    aliases = ["acl"]
    filenames = ["*.acl"]
    mimetypes = ["text/x-acl"]

    tokens = {
        "root": [
            (r"[ \t\f]+", Whitespace),
            (r"\r?\n", Whitespace),
            (r"\\[ \t\f]*\r?\n", Text),                                    # line continuation
            (r"#[ \t]*acl[ \t]*:[ \t]*ignore\b[^\n]*", Comment.Special),
            (r"#[^\n]*", Comment.Single),
            (r'"[^"\n]*"', String.Double),
            (rf"(import)(\s+)({NAME}(?:\.{NAME})*)", bygroups(Keyword.Namespace, Whitespace, Name.Namespace)),
            (r"(import|extends|as)\b", Keyword.Namespace),
            (rf"(program)(\s+)({NAME})", bygroups(Keyword, Whitespace, Name.Function)),
            (rf"(param|observe)(\s+)({NAME})", bygroups(Keyword, Whitespace, Name.Variable)),
            (rf"(use)(\s+)({NAME})", bygroups(Keyword, Whitespace, Keyword.Declaration)),
            (rf"{_KIND}(\s+)({NAME})(?=\s*(?:\{{|like\b))", bygroups(Keyword.Declaration, Whitespace, Name.Class)),
            (rf"{_KIND}(?=\s*\{{)", Keyword.Declaration),
            (rf"({NAME})(\s*)(=)(?!=)", bygroups(Name.Attribute, Whitespace, Operator)),   # key = value
            (rf"{NAME}(?=\()", Name.Function),
            (words(KEYWORDS, prefix=r"\b", suffix=r"\b"), Keyword),
            (r"[+-][xyz](?![A-Za-z0-9_])", Name.Constant),
            (rf"({FLOAT})([ \t]*)({UNIT})", bygroups(Number.Float, Whitespace, Keyword.Type)),
            (FLOAT, Number.Float),                                             # before `2 e`: 2e-5 is a number
            (rf"({INTEGER})([ \t]*)({UNIT})", bygroups(Number.Integer, Whitespace, Keyword.Type)),
            (INTEGER, Number.Integer),
            (NAME, Name),
            (r"\.\.|>=|<=|\+-|[<>=+\-*/^@\u00b1]", Operator),
            (r"[(){}\[\],.]", Punctuation),
        ],
    }
