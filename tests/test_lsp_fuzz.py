"""A small fuzz of `acl lsp` (issue 27): every request at random positions, and with broken
params, in each position encoding a client can negotiate (utf-8, utf-16, utf-32), on a design
with characters of 1 to 4 UTF-8 bytes (and a UTF-16 surrogate pair). No reply is an internal
error or carries a traceback, every range the server returns on the document lies inside its
line in the negotiated units, and the server goes on answering. Seeded: the same requests each run."""
from __future__ import annotations

import json
import random

import pytest

pytest.importorskip("pygls", reason="acl lsp needs the optional extra acl[lsp] (pygls)")

from lsp_client import LspClient  # noqa: E402
from test_lsp_features import MAIN  # noqa: E402

TEXT = MAIN.replace("# a comment", "# a comment: µ, 😀 and 𝜔") + "param g2 = 5 µm * dwel  # typo: a quick fix\n"
LINES = TEXT.split("\n")

POSITIONED = ["textDocument/hover", "textDocument/definition", "textDocument/completion", "textDocument/references",
              "textDocument/prepareRename", "textDocument/rename", "textDocument/documentHighlight",
              "textDocument/signatureHelp"]
WHOLE = ["textDocument/documentSymbol", "textDocument/documentLink", "textDocument/foldingRange",
         "textDocument/semanticTokens/full", "textDocument/codeLens", "textDocument/formatting",
         "textDocument/diagnostic"]
RANGED = ["textDocument/inlayHint", "textDocument/codeAction", "textDocument/rangeFormatting"]


def _units(text: str, enc: str) -> int:
    if enc == "utf-8":
        return len(text.encode("utf-8"))
    if enc == "utf-16":
        return len(text.encode("utf-16-le")) // 2
    return len(text)


def _pos(rng: random.Random) -> dict:
    line = rng.choice([rng.randrange(len(LINES) + 3), rng.randrange(len(LINES)), -1, 2**31 - 1])
    ch = rng.choice([rng.randrange(60), 0, -5, 10**6])
    return {"line": line, "character": ch}


def _params(method: str, u: str, rng: random.Random) -> dict:
    doc = {"textDocument": {"uri": u}}
    if method in POSITIONED:
        p = {**doc, "position": _pos(rng)}
        if method == "textDocument/references":
            p["context"] = {"includeDeclaration": rng.random() < 0.5}
        if method == "textDocument/rename":
            p["newName"] = rng.choice(["g3", "x y", "", "param", "µ", "a" * 300])
        return p
    if method in RANGED:
        a, b = sorted([_pos(rng), _pos(rng)], key=lambda x: (x["line"], x["character"]))
        p = {**doc, "range": {"start": a, "end": b}}
        if method == "textDocument/codeAction":
            p["context"] = {"diagnostics": [{"range": {"start": a, "end": b}, "message": "m", "code": "E201"}]}
        if method == "textDocument/rangeFormatting":
            p["options"] = {"tabSize": 2, "insertSpaces": True}
        return p
    if method == "textDocument/formatting":
        return {**doc, "options": {"tabSize": 2, "insertSpaces": True}}
    return doc


BROKEN = [None, {}, {"textDocument": None}, {"textDocument": {"uri": 5}}, {"textDocument": {"uri": "file:///nope.acl"}},
          {"textDocument": {"uri": "?"}, "position": {"line": "a", "character": None}},
          {"textDocument": {"uri": "?"}, "position": {"line": 1e300, "character": -1e300}},
          {"textDocument": {"uri": "?"}, "range": [1, 2]}, [1, 2, 3], "text"]


def _ranges(x):
    """Every {"start", "end"} range inside a reply."""
    if isinstance(x, dict):
        if set(x) >= {"start", "end"} and isinstance(x["start"], dict) and "character" in x["start"]:
            yield x
        for v in x.values():
            yield from _ranges(v)
    elif isinstance(x, list):
        for v in x:
            yield from _ranges(v)


@pytest.mark.parametrize("enc", ["utf-8", "utf-16", "utf-32"])
def test_random_and_broken_requests_never_reach_a_traceback(enc, tmp_path):
    rng = random.Random(27)
    c = LspClient({"lint": False}, root=tmp_path,
                  capabilities={"general": {"positionEncodings": [enc]},
                                "textDocument": {"rename": {"prepareSupport": True}}})
    try:
        assert c.init_result["capabilities"]["positionEncoding"] == enc
        path = tmp_path / "main.acl"
        path.write_text(TEXT, encoding="utf-8")
        u = c.open(path, TEXT)
        c.wait_for("textDocument/publishDiagnostics", lambda p: p["uri"] == u)
        errors = 0
        for i in range(240):
            method = rng.choice(POSITIONED + WHOLE + RANGED)
            params = _params(method, u, rng) if i % 6 else json.loads(
                json.dumps(rng.choice(BROKEN)).replace('"?"', json.dumps(u)))
            try:
                got = c.request(method, params, timeout=30)
            except RuntimeError as exc:
                errors += 1
                text = str(exc)
                assert "Traceback" not in text and 'File "' not in text, text
                assert "-32603" not in text, (method, params, text)       # no internal error
                continue
            for r in _ranges(got):
                if isinstance(got, dict) and "changes" in got and u not in got["changes"]:
                    continue
                for end in (r["start"], r["end"]):
                    assert 0 <= end["line"] <= len(LINES), (method, params, r)
                    if end["line"] < len(LINES) and method not in ("workspace/symbol",):
                        assert 0 <= end["character"] <= _units(LINES[end["line"]], enc), (method, params, r, enc)
        assert 0 < errors < 240
        assert "300 ms" in c.at("textDocument/hover", u, 10, 8)["contents"]["value"]     # still answering
        assert not [x for x in c.stderr_lines if "Traceback" in x]
    finally:
        c.close()
