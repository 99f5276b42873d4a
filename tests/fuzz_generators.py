"""Generators of hostile inputs for the fuzzing studies (tests/test_fuzz_hostile.py, issue 29).

Grammar-aware mutations of designs (tokens deleted, swapped, duplicated; numbers replaced by extreme, negative,
NaN and infinite values; units replaced by units of another dimension; Unicode look-alikes and zero-width
characters inserted; circular `extends`), mutated data CSVs and schedule.json files, and broken LSP frames.
Each generator is a hypothesis strategy, so a failing input shrinks to a small one and is replayed by its seed.
"""
from __future__ import annotations

import json
import re
from pathlib import Path

from hypothesis import strategies as st

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = sorted((ROOT / "examples").glob("*.acl"))
SOURCES = {p.name: p.read_text(encoding="utf-8") for p in EXAMPLES}

TOKEN = re.compile(r"\s+|[A-Za-z_µ][A-Za-z0-9_]*|\d+(?:\.\d+)?(?:[eE][+-]?\d+)?|\.\.|.", re.S)
NUMBER = re.compile(r"^\d+(?:\.\d+)?(?:[eE][+-]?\d+)?$")
UNIT_WORDS = {"um", "nm", "mm", "m", "kHz", "Hz", "MHz", "V", "mV", "s", "ms", "us", "nN", "N", "Pa", "kPa", "MPa",
              "GPa", "deg", "rad", "kg", "g"}

EXTREME_NUMBERS = ["0", "-0", "1e308", "1e-308", "1e-320", "9" * 400, "1e999", "-1e308", "nan", "inf", "-inf",
                   "0.0000000000000000000001", "123456789012345678901234567890", "-1", "-5"]
WRONG_UNITS = ["kHz", "V", "um", "s", "nN", "Pa", "kg", "deg", "m^3", "1/s", "N/m", "degC", "dB", "µ", "K", "A"]
INVISIBLE = ["\u200b", "\u200d", "\ufeff", "\u00a0", "\u2060", "\u202e"]
LOOKALIKES = {"a": "\u0430", "e": "\u0435", "o": "\u043e", "p": "\u0440", "c": "\u0441", "x": "\u0445",
              "-": "\u2212", "=": "\ua78a", "(": "\uff08", ".": "\u2024", "u": "\u00b5"}


def _tokens(text: str) -> list[str]:
    return TOKEN.findall(text)


@st.composite
def mutated_design(draw) -> str:
    """One example, mutated by one to four grammar-aware operations."""
    name = draw(st.sampled_from(sorted(SOURCES)), label="example")
    units = _tokens(SOURCES[name])
    for _ in range(draw(st.integers(1, 4), label="mutations")):
        if not units:
            break
        op = draw(st.sampled_from(["delete", "duplicate", "swap", "number", "unit", "invisible", "lookalike"]),
                  label="op")
        i = draw(st.integers(0, len(units) - 1), label="at")
        if op == "delete":
            del units[i]
        elif op == "duplicate":
            units.insert(i, units[i])
        elif op == "swap":
            j = draw(st.integers(0, len(units) - 1), label="with")
            units[i], units[j] = units[j], units[i]
        elif op == "number":
            numbers = [k for k, u in enumerate(units) if NUMBER.match(u)]
            if numbers:
                k = draw(st.sampled_from(numbers), label="number at")
                units[k] = draw(st.sampled_from(EXTREME_NUMBERS), label="value")
        elif op == "unit":
            found = [k for k, u in enumerate(units) if u in UNIT_WORDS]
            if found:
                k = draw(st.sampled_from(found), label="unit at")
                units[k] = draw(st.sampled_from(WRONG_UNITS), label="unit")
        elif op == "invisible":
            units.insert(i, draw(st.sampled_from(INVISIBLE), label="char"))
        else:
            word = units[i]
            if word:
                c = draw(st.integers(0, len(word) - 1), label="char at")
                units[i] = word[:c] + LOOKALIKES.get(word[c], word[c]) + word[c + 1:]
    return "".join(units)


def circular_designs(folder: Path) -> list[Path]:
    """Designs that extend each other in a ring, and one that is `like` itself."""
    (folder / "ring_a.acl").write_text('extends "ring_b.acl"\nparam a = 1 um\n')
    (folder / "ring_b.acl").write_text('extends "ring_c.acl"\nparam b = 1 um\n')
    (folder / "ring_c.acl").write_text('extends "ring_a.acl"\nparam c = 1 um\n')
    (folder / "self_like.acl").write_text("import stdlib.capsules\ncapsule a like a { }\ncapsule b like b.c { }\n")
    return [folder / "ring_a.acl", folder / "self_like.acl"]


CSV_CELLS = ["", "nan", "inf", "-inf", "1e308", "-1e308", "1e-320", "9" * 5000, "0", "-0", "abc", "1,2", '"', '""',
             "125 kHz @ 1 V", "125 kHz @ -1 V", "125 kHz @ 1e308 V", "0 Hz @ 1 V", "1e999 kHz @ 1 V",
             "125 kHz @ 1 V + 125 kHz @ 2 V", "um", "m", "degC", "µ", "\u200b", "\x00", "é"]


@st.composite
def mutated_csv(draw, text: str) -> str:
    """A data CSV with cells replaced, rows duplicated or deleted, and columns dropped."""
    rows = [r.split(",") for r in text.splitlines()]
    for _ in range(draw(st.integers(1, 5), label="mutations")):
        op = draw(st.sampled_from(["cell", "row_dup", "row_del", "col_del", "header"]), label="op")
        i = draw(st.integers(0, len(rows) - 1), label="row")
        if op == "cell" and rows[i]:
            j = draw(st.integers(0, len(rows[i]) - 1), label="col")
            rows[i][j] = draw(st.sampled_from(CSV_CELLS), label="value")
        elif op == "row_dup":
            rows.insert(i, list(rows[i]))
        elif op == "row_del" and len(rows) > 1:
            del rows[i]
        elif op == "col_del" and rows[0]:
            j = draw(st.integers(0, len(rows[0]) - 1), label="col")
            rows = [r[:j] + r[j + 1:] for r in rows]
        elif op == "header":
            j = draw(st.integers(0, len(rows[0]) - 1), label="col") if rows[0] else 0
            if rows[0]:
                rows[0][j] = draw(st.sampled_from(["value", "VALUE", "set:gap", "set:", "drive", "x" * 300, ""]))
    return "\n".join(",".join(r) for r in rows) + "\n"


JSON_VALUES = [None, True, False, 0, -1, 1e308, -1e308, "nan", "", "x", [], {}, [1, 2], {"a": 1}, 10 ** 30,
               0.5, 1e-320]


@st.composite
def mutated_schedule(draw, doc: dict) -> str:
    """A schedule.json with values replaced at random paths, lists truncated or duplicated."""
    doc = json.loads(json.dumps(doc))

    def paths(node, prefix=()):
        yield prefix
        if isinstance(node, dict):
            for k, v in node.items():
                yield from paths(v, prefix + (k,))
        elif isinstance(node, list):
            for k, v in enumerate(node[:5]):
                yield from paths(v, prefix + (k,))

    every = [p for p in paths(doc) if p]
    for _ in range(draw(st.integers(1, 4), label="mutations")):
        path = draw(st.sampled_from(every), label="path")
        parent = doc
        for k in path[:-1]:
            parent = parent[k]
        op = draw(st.sampled_from(["value", "delete", "duplicate"]), label="op")
        try:
            if op == "value":
                parent[path[-1]] = draw(st.sampled_from(JSON_VALUES), label="value")
            elif op == "delete":
                del parent[path[-1]]
            elif isinstance(parent, list):
                parent.insert(path[-1], parent[path[-1]])
        except (KeyError, IndexError, TypeError):
            pass
        every = [p for p in paths(doc) if p]
        if not every:
            break
    return json.dumps(doc)


def frame(body: bytes, length: int | None = None, header_extra: bytes = b"") -> bytes:
    """One LSP message: Content-Length header (``length`` overrides the true one) and body."""
    n = len(body) if length is None else length
    return b"Content-Length: " + str(n).encode() + b"\r\n" + header_extra + b"\r\n" + body


@st.composite
def broken_frames(draw) -> list[bytes]:
    """A burst of malformed LSP traffic: wrong lengths, garbage headers, non-JSON bodies, huge numbers."""
    out = []
    for _ in range(draw(st.integers(1, 6), label="frames")):
        kind = draw(st.sampled_from(["short", "long", "garbage_header", "not_json", "bad_utf8", "huge_int",
                                     "no_method", "array", "negative"]), label="kind")
        body = json.dumps({"jsonrpc": "2.0", "id": draw(st.integers(1000, 2000)), "method": "textDocument/hover",
                           "params": {"textDocument": {"uri": "file:///nowhere.acl"},
                                      "position": {"line": 0, "character": 0}}}).encode()
        if kind == "short":
            out.append(frame(body, len(body) - draw(st.integers(1, 10))))
        elif kind == "long":        # within the one-message limit: an absurd length is tests/test_lsp_stream.py's
            out.append(frame(body, len(body) + draw(st.integers(1, 5000))))
        elif kind == "garbage_header":
            out.append(b"Content-Lenght: 12\r\n\r\n{}" + draw(st.binary(max_size=40)))
        elif kind == "not_json":
            out.append(frame(b"{not json"))
        elif kind == "bad_utf8":
            out.append(frame(b'{"jsonrpc": "2.0", "method": "\xff\xfe"}'))
        elif kind == "huge_int":
            out.append(frame(b'{"jsonrpc": "2.0", "id": ' + b"9" * 5000 + b', "method": "shutdown"}'))
        elif kind == "no_method":
            out.append(frame(b'{"jsonrpc": "2.0", "id": 77}'))
        elif kind == "array":
            out.append(frame(b"[1, 2, 3]"))
        else:
            out.append(b"Content-Length: -5\r\n\r\n")
    return out
