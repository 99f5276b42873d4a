"""`acl lsp` driven through the real protocol: a subprocess `python -m acl lsp` spoken to over
stdio with Content-Length framed JSON-RPC (tests/lsp_client.py)."""
from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("pygls", reason="acl lsp needs the optional extra acl[lsp] (pygls)")
pytest.importorskip("lsprotocol", reason="acl lsp needs the optional extra acl[lsp] (lsprotocol)")

from lsp_client import ROOT, LspClient, uri  # noqa: E402

DESIGN = """\
import stdlib.media
import stdlib.capsules
import stdlib.beams
import stdlib.transducers
use medium media.pbs
use transducer transducers.contact_piezo

param dwell = 300 ms
beam arm like beams.cantilever50 { clamp = (0, 0, 0) }
capsule c1 like capsules.design1 { }
capsule c2 like capsules.design2 { center = (300 um, 0, 100 um) }
capsule c3 like capsules.design3 { center = (600 um, 0, 100 um) }
mount c1 on arm.tip
fix c2
fix c3

program ramp {
  drive 125 kHz @ 2 V for dwell
}
"""

# Paper Table S1: theoretical natural frequency (kHz) of designs 1-3; the same 3 % as `acl analyze`
# (tests/test_physics_resonance.py).
TABLE_S1_KHZ = {"design1": 122.0, "design2": 84.9, "design3": 171.8}


@pytest.fixture(scope="module")
def client():
    c = LspClient({"lint": False, "debounce": 0.02})
    yield c
    c.close()


def _line(text: str, needle: str) -> int:
    return next(i for i, ln in enumerate(text.split("\n")) if needle in ln)


def _open(client, path: Path, text: str, version: int = 1) -> tuple[str, dict]:
    path.write_text(text, encoding="utf-8")
    u = client.open(path, text, version)
    return u, client.wait_for("textDocument/publishDiagnostics", lambda p: p["uri"] == u and p.get("version") == version)


def _hover_text(client, u, line, character) -> str:
    got = client.at("textDocument/hover", u, line, character)
    assert got is not None, f"no hover at {line}:{character}"
    return got["contents"]["value"]


def test_initialize_advertises_every_feature(client):
    caps = client.init_result["capabilities"]
    for key in ("hoverProvider", "definitionProvider", "completionProvider", "documentSymbolProvider",
                "codeActionProvider", "documentFormattingProvider"):
        assert caps.get(key), key
    assert client.init_result["serverInfo"]["name"] == "acl"


def test_diagnostics_are_those_of_acl_check(client, tmp_path):
    bad = DESIGN.replace("capsules.design2", "capsules.desing2").replace("param dwell = 300 ms", "param dwell = 300 ms + 2 V")
    bad += "beam b2 like beams.cantilever50 { clamp = (0, 0, 0), lenght = 40 um }\n"
    path = tmp_path / "bad.acl"
    u, pub = _open(client, path, bad)
    proc = subprocess.run([sys.executable, "-m", "acl", "check", "--output-format", "json", str(path)],
                          capture_output=True, text=True, cwd=ROOT, env={"PYTHONPATH": str(ROOT), "PATH": ""})
    cli = json.loads(proc.stdout)["diagnostics"]
    assert len(cli) >= 3
    want = sorted((d["code"], d["line"] - 1, d["column"] - 1, d["hint"]) for d in cli)
    got = sorted((d["code"], d["range"]["start"]["line"], d["range"]["start"]["character"],
                  d["message"].split("\nhelp: ", 1)[1].split("\n")[0] if "\nhelp: " in d["message"] else None)
                 for d in pub["diagnostics"])
    assert got == want
    for d in pub["diagnostics"]:
        assert d["source"] == "acl" and d["severity"] in (1, 2)


def test_did_change_updates_diagnostics(client, tmp_path):
    path = tmp_path / "edit.acl"
    u, pub = _open(client, path, DESIGN)
    assert pub["diagnostics"] == []
    ln = _line(DESIGN, "capsule c1")
    col = DESIGN.split("\n")[ln].index("design1")
    client.edit(u, 2, ln, col, col + len("design1"), "desing1")        # incremental edit: a typo
    pub = client.wait_for("textDocument/publishDiagnostics", lambda p: p["uri"] == u and p.get("version") == 2)
    e201 = [d for d in pub["diagnostics"] if d["code"] == "E201"]
    assert len(e201) == 1 and "did you mean `design1`?" in e201[0]["message"]
    assert e201[0]["range"]["start"] == {"line": ln, "character": DESIGN.split("\n")[ln].index("capsules")}
    client.edit(u, 3, ln, col, col + len("desing1"), "design1")        # fixed again
    pub = client.wait_for("textDocument/publishDiagnostics", lambda p: p["uri"] == u and p.get("version") == 3)
    assert pub["diagnostics"] == []


def test_debounce_publishes_once_for_a_burst_of_changes(tmp_path):
    c = LspClient({"lint": False, "debounce": 0.5})
    try:
        path = tmp_path / "burst.acl"
        u, _ = _open(c, path, DESIGN)
        for v in range(2, 7):
            c.change(u, v, DESIGN + f"# edit {v}\n")
        pub = c.wait_for("textDocument/publishDiagnostics", lambda p: p["uri"] == u)
        assert pub["version"] == 6          # versions 2..5 were superseded before the pause ended
    finally:
        c.close()


@pytest.mark.parametrize("template", sorted(TABLE_S1_KHZ))
def test_hover_on_table_s1_capsule_shows_its_resonance(client, tmp_path, template):
    path = tmp_path / "s1.acl"
    u, _ = _open(client, path, DESIGN)
    name = {"design1": "c1", "design2": "c2", "design3": "c3"}[template]
    ln = _line(DESIGN, f"capsule {name}")
    text_line = DESIGN.split("\n")[ln]
    for col in (text_line.index(name), text_line.index(template) + 2):    # the capsule, and its stdlib template
        text = _hover_text(client, u, ln, col)
        m = re.search(r"\| 1 \| ([\d.]+) \| ([\d.]+)", text)
        assert m, text
        f_khz, q = float(m.group(1)), float(m.group(2))
        assert abs(f_khz / TABLE_S1_KHZ[template] - 1) < 0.03, (template, f_khz)
        assert q > 1
    own = _hover_text(client, u, ln, text_line.index(name))
    assert "phase of `jet`" in own and "125 kHz" in own        # phase at the program's frequency


def test_hover_quantity_param_beam_and_rule(client, tmp_path):
    text = DESIGN + "# acl: ignore[ACL601] kept for a later program\n"
    path = tmp_path / "hover.acl"
    u, _ = _open(client, path, text)
    ln = _line(text, "drive 125 kHz")
    col = text.split("\n")[ln].index("125")
    assert "**125000 Hz**" in _hover_text(client, u, ln, col)
    assert "frequency" in _hover_text(client, u, ln, col + 5)
    ln_p = _line(text, "param dwell")
    assert "**0.3 s**" in _hover_text(client, u, ln_p, text.split("\n")[ln_p].index("300"))
    assert "= **0.3 s**" in _hover_text(client, u, ln, text.split("\n")[ln].index("dwell") + 1)
    # beam: the tip stiffness of paper Eq. 1 for the resolved beam
    import acl
    from acl.physics.beams import eq1_small_force_stiffness

    b = acl.load(str(path)).beam("arm")
    k = eq1_small_force_stiffness(b.length, b.rigid_length, b.bending_stiffness)
    ln_b = _line(text, "beam arm")
    hv = _hover_text(client, u, ln_b, 6)
    got = float(re.search(r"k = ([\d.e+-]+) N/m", hv).group(1))
    assert got == pytest.approx(k, rel=1e-3)
    # a lint code in a suppression comment: the rule's text from the registry
    from acl.lint.registry import load_rules

    ln_c = _line(text, "ignore[ACL601]")
    hv = _hover_text(client, u, ln_c, text.split("\n")[ln_c].index("ACL601") + 2)
    assert load_rules()["ACL601"].summary in hv and "unused-declaration" in hv


def test_definition_across_imports_and_stdlib(client, tmp_path):
    path = tmp_path / "defs.acl"
    u, _ = _open(client, path, DESIGN)
    lines = DESIGN.split("\n")
    ln = _line(DESIGN, "capsule c1")
    got = client.at("textDocument/definition", u, ln, lines[ln].index("design1") + 1)
    stdlib_caps = ROOT / "stdlib" / "capsules.acl"
    assert got["uri"] == uri(stdlib_caps)
    decl_line = _line(stdlib_caps.read_text(), "capsule design1")
    assert got["range"]["start"] == {"line": decl_line, "character": len("capsule ")}
    # `arm` in `mount c1 on arm.tip` -> the beam's declaration in this file
    ln_m = _line(DESIGN, "mount c1")
    got = client.at("textDocument/definition", u, ln_m, lines[ln_m].index("arm") + 1)
    assert got["uri"] == u and got["range"]["start"]["line"] == _line(DESIGN, "beam arm")
    # an import -> the module file; a module alias -> the module file
    got = client.at("textDocument/definition", u, _line(DESIGN, "import stdlib.beams"), 10)
    assert got["uri"] == uri(ROOT / "stdlib" / "beams.acl")
    got = client.at("textDocument/definition", u, ln, lines[ln].index("capsules") + 1)
    assert got["uri"] == uri(stdlib_caps)
    # a name in an expression -> its param
    ln_d = _line(DESIGN, "drive 125")
    got = client.at("textDocument/definition", u, ln_d, lines[ln_d].index("dwell") + 1)
    assert got["range"]["start"]["line"] == _line(DESIGN, "param dwell")


def _labels(result) -> list[str]:
    items = result["items"] if isinstance(result, dict) else result
    return [i["label"] for i in items]


def test_completion_by_context(client, tmp_path):
    text = DESIGN + "\ncapsule c4 {\n  orifice o { radius = 10 }\n  \n}\n"
    path = tmp_path / "comp.acl"
    u, _ = _open(client, path, text)
    lines = text.split("\n")
    # top level: declaration kinds and statements
    top = _labels(client.at("textDocument/completion", u, len(lines) - 1, 0))
    assert {"capsule", "beam", "param", "program", "import"} <= set(top)
    # keys of the declaration at the cursor
    ln_blank = len(lines) - 3
    keys = _labels(client.at("textDocument/completion", u, ln_blank, 2))
    assert {"center", "thrust", "cavity", "orifice"} <= set(keys) and "clamp" not in keys
    # units of the key's dimension: radius is a length
    ln_o = _line(text, "orifice o")
    units = _labels(client.at("textDocument/completion", u, ln_o, len(lines[ln_o].rstrip("}").rstrip()) + 1))
    assert "um" in units and "mm" in units and "kHz" not in units and "V" not in units
    # members of a module, names in scope, stdlib modules
    ln_c = _line(text, "capsule c1")
    members = _labels(client.at("textDocument/completion", u, ln_c, lines[ln_c].index("design1")))
    assert {"design1", "design2", "design3"} <= set(members)
    ln_d = _line(text, "drive 125")
    scope = _labels(client.at("textDocument/completion", u, ln_d, lines[ln_d].index("dwell")))
    assert {"dwell", "arm", "c1", "capsules"} <= set(scope)
    client.change(u, 2, text + "import \n")
    n = len(text.split("\n")) - 1
    mods = _labels(client.at("textDocument/completion", u, n, len("import ")))
    assert {"stdlib.capsules", "stdlib.media", "stdlib.beams"} <= set(mods)
    # inside a program: its steps
    steps = _labels(client.at("textDocument/completion", u, ln_d, 2))
    assert {"drive", "sweep", "pause"} <= set(steps)


def test_document_symbols_outline(client, tmp_path):
    path = tmp_path / "sym.acl"
    u, _ = _open(client, path, DESIGN)
    syms = client.request("textDocument/documentSymbol", {"textDocument": {"uri": u}})
    by = {s["name"]: s for s in syms}
    assert {"dwell", "arm", "c1", "c2", "c3", "ramp", "stdlib.capsules"} <= set(by)
    assert by["c1"]["detail"] == "capsule like capsules.design1"
    assert by["arm"]["selectionRange"]["start"] == {"line": _line(DESIGN, "beam arm"), "character": 5}
    assert [c["name"] for c in by["ramp"]["children"]] == ["1. drive"]


def test_code_actions_fix_every_did_you_mean(client, tmp_path):
    bad = DESIGN.replace("capsules.design2", "capsules.desing2").replace("use medium", "use meduim")
    bad = bad.replace("drive 125 kHz", "drive 125 khz")
    bad = bad.replace("program ramp", "capsule c5 { center = (0, 300 um, 100 um), cavity cylinder { radius = 25 um, height = 33 um }, "
                      "orifice jet { raduis = 10 um } }\nprogram ramp")
    path = tmp_path / "fix.acl"
    u, pub = _open(client, path, bad)
    hinted = [d for d in pub["diagnostics"] if "did you mean" in d["message"]]
    assert len(hinted) >= 4, pub["diagnostics"]
    assert {"E201", "E302"} <= {d["code"] for d in hinted}
    text = bad
    for d in hinted:
        acts = client.request("textDocument/codeAction", {"textDocument": {"uri": u}, "range": d["range"],
                                                          "context": {"diagnostics": [d]}})
        assert acts, d
        edit = acts[0]["edit"]["changes"][u][0]
        assert acts[0]["kind"] == "quickfix"
        lines = text.split("\n")
        r = edit["range"]
        ln = lines[r["start"]["line"]]
        lines[r["start"]["line"]] = ln[:r["start"]["character"]] + edit["newText"] + ln[r["end"]["character"]:]
        text = "\n".join(lines)
    assert text == DESIGN.replace("program ramp", "capsule c5 { center = (0, 300 um, 100 um), cavity cylinder { radius = 25 um, "
                                  "height = 33 um }, orifice jet { radius = 10 um } }\nprogram ramp")
    client.change(u, 2, text)
    pub = client.wait_for("textDocument/publishDiagnostics", lambda p: p["uri"] == u and p.get("version") == 2)
    assert not any("did you mean" in d["message"] for d in pub["diagnostics"])


def test_lint_findings_follow_the_check_diagnostics(tmp_path):
    c = LspClient({"lint": True, "debounce": 0.02, "lint_delay": 0.05})
    try:
        path = tmp_path / "lint.acl"
        text = DESIGN + "param unused_gap = 30 um\n"
        u, first = _open(c, path, text)
        assert first["diagnostics"] == []          # the check stage is clean
        later = c.wait_for("textDocument/publishDiagnostics",
                           lambda p: p["uri"] == u and any(d["code"] == "ACL601" for d in p["diagnostics"]), timeout=120)
        from acl.lint import find_config, lint_file, load_config, load_rules

        acl601 = next(d for d in later["diagnostics"] if d["code"] == "ACL601")
        assert acl601["codeDescription"]["href"] == uri(ROOT / "docs" / "rules.md") + "#acl601"
        assert "## ACL601" in (ROOT / "docs" / "rules.md").read_text()
        rep = lint_file(str(path), load_config(find_config(str(path)), load_rules()))
        assert sorted((d.code, d.span.line - 1) for d in rep.findings) == \
            sorted((d["code"], d["range"]["start"]["line"]) for d in later["diagnostics"])
    finally:
        c.close()


def test_lsp_without_pygls_is_a_coded_diagnostic():
    code = ("import sys; sys.modules['pygls'] = None; sys.modules['lsprotocol'] = None\n"
            "from acl.cli import main; sys.exit(main(['lsp']))")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT,
                          env={"PYTHONPATH": str(ROOT), "PATH": ""}, timeout=60)
    assert proc.returncode == 2
    assert "E-DEPENDENCY" in proc.stderr and "acl[lsp]" in proc.stderr and "Traceback" not in proc.stderr


def _corpus():
    files = sorted((ROOT / "examples").glob("*.acl")) + sorted((ROOT / "stdlib").glob("*.acl")) + \
        sorted((ROOT / "tests" / "bad").glob("*.acl"))
    return [f for f in files if f.stat().st_size < 200_000]


def test_incremental_parse_equals_whole_file_parse():
    from acl.diagnostics import DiagnosticError
    from acl.lsp.incremental import IncrementalParser
    from acl.syntax.parser import parse_module

    for f in _corpus():
        text = f.read_text(encoding="utf-8", errors="replace")
        got = IncrementalParser().parse(text, str(f))
        try:
            want = parse_module(text, str(f))
        except DiagnosticError:
            assert got is None, f      # a file with syntax errors always takes the whole-file path
            continue
        assert got == want, f
    # its chunker (with remembered line depths) cuts exactly where the parser's does
    from acl.syntax.parser import statement_chunks as _statement_chunks

    ip = IncrementalParser()
    for f in _corpus():
        lines = (f.read_text(encoding="utf-8", errors="replace") + "\n").split("\n")
        assert list(ip._chunks(lines)) == list(_statement_chunks(lines)), f
    # a broken statement: parse() refuses, parse_partial() keeps every other statement
    broken = DESIGN.replace("fix c3", "fix c3 (")
    assert IncrementalParser().parse(broken, "b.acl") is None
    part = IncrementalParser().parse_partial(broken, "b.acl")
    whole = parse_module(DESIGN, "b.acl").statements
    assert len(part.statements) == len(whole) - 1
    # edits through one parser (cached statements reused) still give the whole-file tree
    p = IncrementalParser()
    text = DESIGN
    for old, new in (("300 ms", "250 ms"), ("fix c3", "fix c3\nparam extra = 2 um"), ("c2", "c22"), ("{ }", "{\n}")):
        text = text.replace(old, new)
        assert p.parse(text, "d.acl") == parse_module(text, "d.acl"), (old, new)
    assert p.parse(text, "other.acl") == parse_module(text, "other.acl")     # another file name: no stale spans
    # the parser's limits hold on the incremental path too (nesting checked per statement): over
    # one, parse() refuses, and the whole-file parse reports it (E104, E103)
    from acl.syntax.parser import MAX_NESTING

    deep = text + "param deep = " + "(" * (MAX_NESTING + 1) + "1 um" + ")" * (MAX_NESTING + 1) + "\n"
    assert p.parse(deep, "other.acl") is None
    with pytest.raises(DiagnosticError, match="nesting"):
        parse_module(deep, "other.acl")
    ok = text + "param deep = " + "(" * MAX_NESTING + "1 um" + ")" * MAX_NESTING + "\n"
    assert p.parse(ok, "other.acl") == parse_module(ok, "other.acl")
    assert p.parse(text + "# a NUL: \x00\n", "other.acl") is None



@pytest.mark.parametrize("seed", range(3))
def test_incremental_parse_equals_whole_file_parse_over_random_edits(seed):
    """One parser through 60 random line edits of an example (a line changed, broken, inserted,
    deleted, duplicated; edits near the start and end; runs of edits that do not parse): after each,
    parse() gives exactly the whole-file tree, or None where the whole-file parse fails. This holds
    the reuse of unchanged chunks before and after an edit (IncrementalParser._unchanged)."""
    import random

    from acl.diagnostics import DiagnosticError
    from acl.lsp.incremental import IncrementalParser
    from acl.syntax.parser import parse_module

    rng = random.Random(seed)
    lines = (ROOT / "examples" / "fig4h_unequal_pair.acl").read_text(encoding="utf-8").split("\n")
    p = IncrementalParser()
    reused = 0
    for step in range(60):
        i = rng.choice([0, 1, len(lines) - 2, len(lines) - 1, rng.randrange(len(lines))])
        op = rng.choice(["value", "value", "break", "insert", "delete", "dup", "comment"])
        before = list(lines)
        if op == "value":
            lines[i] = lines[i].replace(" um", f" um + {step} um", 1) if " um" in lines[i] else lines[i] + "  # x"
        elif op == "break":                # broken for this step only (then the line is as it was)
            broken = lines[:i] + [lines[i] + " ("] + lines[i + 1:]
            assert p.parse("\n".join(broken), "r.acl") is None or "#" in lines[i]
            continue
        elif op == "insert":
            lines.insert(i, f"param extra{step} = {step} um")
        elif op == "delete" and len(lines) > 3:
            del lines[i]
        elif op == "dup":
            lines.insert(i, lines[i])
        else:
            lines[i] = "# " + lines[i]
        text = "\n".join(lines)
        head, tail, _ = p._unchanged((text + "\n").split("\n"))
        got = p.parse(text, "r.acl")
        try:
            want = parse_module(text, "r.acl")
        except DiagnosticError:
            assert got is None, (step, op, i)
            lines = before                 # an edit that broke the text is undone (as a user would)
            continue
        assert got == want, (step, op, i)
        reused += bool(head) + bool(tail and tail.chunks)
    assert reused > 20         # the reuse paths were taken


def _apply(text: str, edits: list[dict]) -> str:
    lines = text.split("\n")
    offsets = [0]
    for ln in lines:
        offsets.append(offsets[-1] + len(ln) + 1)

    def off(p):
        return offsets[p["line"]] + p["character"]

    for e in sorted(edits, key=lambda e: off(e["range"]["start"]), reverse=True):
        text = text[:off(e["range"]["start"])] + e["newText"] + text[off(e["range"]["end"]):]
    return text


def test_formatting_is_acl_fmt(client, tmp_path):
    from acl.fmt import format_source

    messy = DESIGN.replace("param dwell = 300 ms", "param   dwell=300 ms    # the step").replace(
        "capsule c1 like capsules.design1 { }", "capsule c1 like capsules.design1 {  }")
    assert format_source(messy, "m.acl") != messy
    path = tmp_path / "messy.acl"
    u, _ = _open(client, path, messy)
    opts = {"textDocument": {"uri": u}, "options": {"tabSize": 2, "insertSpaces": True}}
    edits = client.request("textDocument/formatting", opts)
    assert edits
    formatted = _apply(messy, edits)
    assert formatted == format_source(messy, str(path))
    client.change(u, 2, formatted)
    assert client.request("textDocument/formatting", opts) == []       # idempotent: nothing left to do
    client.change(u, 3, formatted + "param broken = (\n")
    assert client.request("textDocument/formatting", opts) is None     # syntax errors: left alone


def test_quick_fix_picks_the_misspelt_part_and_skips_ambiguous_hints():
    from acl.lsp.actions import fix

    line = "capsule c1 like capsules.desing1 { }"
    a = line.index("capsules")
    assert fix(line, a, a + len("capsules.desing1"), "did you mean `design1`?") == (a + 9, a + 16, "design1")
    assert fix("  drive 125 mhz @ 1 V", 8, 15, "did you mean `MHz (or mHz?)`?") is None
    assert fix("use meduim media.pbs", 4, 10, "did you mean `medium`?") == (4, 10, "medium")
    assert fix("x", 0, 1, "stdlib modules: media, beams") is None


def test_hover_on_keys_and_completion_of_capsule_members(client, tmp_path):
    text = DESIGN + "observe gap1 = gap(c1.jet, c2.jet)\n"
    path = tmp_path / "keys.acl"
    u, _ = _open(client, path, text)
    ln = _line(text, "capsule c2")
    hv = _hover_text(client, u, ln, text.split("\n")[ln].index("center") + 1)
    assert hv.startswith("**capsule.center**") and "`m`" in hv
    ln_o = _line(text, "observe gap1")
    members = _labels(client.at("textDocument/completion", u, ln_o, text.split("\n")[ln_o].index("jet")))
    assert members == ["jet"]


def test_every_request_anywhere_in_any_corpus_file_answers_without_error(client):
    """Hover, definition, completion and symbols at many positions of every example, stdlib module
    and bad input: the server answers each (None is an answer) and never returns an error."""
    for f in _corpus():
        text = f.read_text(encoding="utf-8", errors="replace")
        u = client.open(f, text, 1)
        client.request("textDocument/documentSymbol", {"textDocument": {"uri": u}})
        lines = text.split("\n")
        for ln in range(0, len(lines), max(1, len(lines) // 12)):
            for ch in sorted({0, len(lines[ln]) // 3, len(lines[ln]) // 2, len(lines[ln])}):
                for method in ("textDocument/hover", "textDocument/definition", "textDocument/completion"):
                    client.at(method, u, ln, ch)       # raises on a JSON-RPC error
        client.request("textDocument/codeAction", {"textDocument": {"uri": u}, "range": {
            "start": {"line": 0, "character": 0}, "end": {"line": len(lines) - 1, "character": 0}},
            "context": {"diagnostics": []}})
        client.notify("textDocument/didClose", {"textDocument": {"uri": u}})
    assert client.proc.poll() is None


def test_errors_in_an_imported_file_show_on_its_import(client, tmp_path):
    (tmp_path / "parts.acl").write_text("param size = 10 um\nparam broken = (3 um\n", encoding="utf-8")
    text = "import parts\nparam twice = 2 * parts.size\n"
    path = tmp_path / "main.acl"
    u, pub = _open(client, path, text)
    proc = subprocess.run([sys.executable, "-m", "acl", "check", "--output-format", "json", str(path)],
                          capture_output=True, text=True, cwd=ROOT, env={"PYTHONPATH": str(ROOT), "PATH": ""})
    cli = json.loads(proc.stdout)["diagnostics"]
    assert any(d["file"].endswith("parts.acl") for d in cli)
    assert sorted(d["code"] for d in pub["diagnostics"]) == sorted(d["code"] for d in cli)
    imported = [d for d in pub["diagnostics"] if "parts.acl:2:" in d["message"]]
    assert len(imported) == sum(d["file"].endswith("parts.acl") for d in cli)
    for d in imported:
        assert d["range"]["start"] == {"line": 0, "character": 0} and d["range"]["end"]["character"] == len("import parts")


def test_definition_into_a_sibling_file_and_use_completion(client, tmp_path):
    (tmp_path / "parts.acl").write_text("# shared sizes\nparam size = 10 um\n", encoding="utf-8")
    text = 'import "parts.acl" as p\nimport stdlib.media\nparam twice = 2 * p.size\nuse medium \n'
    path = tmp_path / "main.acl"
    u, _ = _open(client, path, text)
    got = client.at("textDocument/definition", u, 2, text.split("\n")[2].index("size") + 1)
    assert got == {"uri": uri(tmp_path / "parts.acl"),
                   "range": {"start": {"line": 1, "character": 6}, "end": {"line": 1, "character": 10}}}
    got = client.at("textDocument/definition", u, 0, 3)            # the import line itself
    assert got["uri"] == uri(tmp_path / "parts.acl")
    media = _labels(client.at("textDocument/completion", u, 3, len("use medium ")))
    assert "media.pbs" in media and all(m.startswith("media.") for m in media)


def test_positions_are_utf16_code_units(client, tmp_path):
    """A non-BMP character (2 UTF-16 units) before a diagnostic and a hover on the same line."""
    line = 'beam b2 like beams.cantilever50 { clamp = (0, 0, 0), material = "\U0001F600", lenght = 40 um }'
    text = DESIGN + line + "\n"
    path = tmp_path / "utf16.acl"
    u, pub = _open(client, path, text)
    ln = len(DESIGN.split("\n")) - 1
    e203 = next(d for d in pub["diagnostics"] if d["code"] == "E203")
    assert e203["range"]["start"] == {"line": ln, "character": line.index("lenght") + 1}
    hv = client.at("textDocument/hover", u, ln, line.index("40 um") + 1 + 1)
    assert "**4e-05 m**" in hv["contents"]["value"]
    assert hv["range"]["start"]["character"] == line.index("40 um") + 1
    acts = client.request("textDocument/codeAction", {"textDocument": {"uri": u}, "range": e203["range"],
                                                      "context": {"diagnostics": [e203]}})
    edit = acts[0]["edit"]["changes"][u][0]
    assert edit["newText"] == "length" and edit["range"]["start"]["character"] == line.index("lenght") + 1


def test_hover_on_a_facing_pair_shows_the_coupled_modes_with_phases(client):
    path = ROOT / "examples" / "fig4_facing_pair.acl"
    text = path.read_text(encoding="utf-8")
    u = client.open(path, text, 1)
    client.wait_for("textDocument/publishDiagnostics", lambda p: p["uri"] == u)
    ln = _line(text, "capsule left")
    hv = _hover_text(client, u, ln, len("capsule l"))
    import acl
    from acl.analysis import acoustics as AC

    if not hasattr(AC, "coupled_modes"):
        pytest.skip("this physics has no coupled modes")
    modes = AC.coupled_modes(acl.load(str(path)))
    assert "with its neighbours" in hv
    for m in modes:
        assert f"| {m.frequency_hz / 1e3:.1f} |" in hv
    assert "(180 deg)" in hv          # the antisymmetric mode: the two interfaces in antiphase
    client.notify("textDocument/didClose", {"textDocument": {"uri": u}})
