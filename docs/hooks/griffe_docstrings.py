"""griffe extension for the API reference (mkdocs.yml, mkdocstrings): acl's docstrings are plain text with
``>>>`` sessions and Sphinx roles; on the site the sessions become ``pycon`` code blocks (markdown would
read ``>>>`` as nested quotes) and ``:class:`~x.Y``` becomes ``x.Y`` in code."""
from __future__ import annotations

import re

import griffe

ROLE = re.compile(r":(?:class|func|mod|meth|attr|data|exc):`~?([^`]+)`")


def fence_sessions(text: str) -> str:
    """Each ``>>>`` session (its statements and the output lines after them, up to a blank line) fenced."""
    out, session = [], []
    for line in text.split("\n") + [""]:
        stripped = line.strip()
        if stripped.startswith((">>>", "...")) or (session and stripped):
            session.append(stripped if stripped.startswith((">>>", "...")) else line.strip())
            continue
        if session:
            out += ["```pycon", *session, "```"]
            session = []
        out.append(line)
    return "\n".join(out[:-1])


class DocstringsForTheSite(griffe.Extension):
    def on_object(self, *, obj, **kwargs) -> None:
        if obj.docstring is not None:
            obj.docstring.value = fence_sessions(ROLE.sub(r"`\1`", obj.docstring.value))
