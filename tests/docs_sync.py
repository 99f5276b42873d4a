"""Numbers in README.md and docs/**/*.md come from runs that a test repeats (tests/test_docs_sync.py).

Generated parts of a page are marked with HTML comments (invisible once rendered):

``<!-- doc: $ acl ARGS -->`` ... ``<!-- /doc -->``
    the output (stdout and stderr, as a terminal shows them) of ``acl ARGS``, as a fenced block.
    A command that must fail ends with ``-> exit N``.
``<!-- doc: = EXPR -->VALUE<!-- /doc -->``
    an inline value: the Python expression EXPR, with ``acl``, ``json_of("ARGS")`` (the JSON output
    of ``acl ARGS --output-format json``, cached), ``out_of("ARGS")`` and ``ci(d, ...)`` (a value
    and its 95 % interval from a report entry, e.g. ``48.6 um [48.4, 48.8]``), ``block(obj)`` (a
    fenced JSON block).
``<!-- doc: doctest -->`` ```` ```python ```` ... ``<!-- /doc -->``
    a ``>>>`` session; each statement is run and the lines after it replaced by what it prints.
``<!-- doc-run: acl ARGS -->``
    runs ``acl ARGS`` and shows nothing (data a later marker uses, e.g. ``acl synth``).
``<!-- doc-py: STATEMENTS -->``
    runs Python statements (imports, small helper functions) and shows nothing; the names they
    define are available to the later markers of the page.

A marker quoted in inline code (right after a backtick) is left alone.
A page is stale when its text differs from a fresh run other than in numbers that agree to 0.2 %
(magnitudes below 1e-20 in SI, solver residuals, are noise); JSON blocks show 6 significant digits.
Every page runs in a fresh scratch folder holding copies of ``examples/`` and ``samples/``, in
page order, so commands may use files made by earlier ones and nothing is written to the repository.

Regenerate after a change that moves numbers (physics, fit, output format):

    python tests/docs_sync.py --update            # every page
    python tests/docs_sync.py --update docs/fit.md
    python tests/docs_sync.py                     # check only: prints a diff, exit 1 if stale
"""
from __future__ import annotations

import contextlib
import difflib
import io
import json
import os
import re
import shlex
import shutil
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PAGES = ["README.md", *sorted(str(p.relative_to(ROOT)) for p in (ROOT / "docs").rglob("*.md"))]   # with tutorials/, how-to/, ...
# a marker quoted in inline code (after a backtick) is text, not a marker
MARK = re.compile(r"(?<!`)<!-- doc-run: (?P<run>.*?) -->|(?<!`)<!-- doc-py:(?P<py>.*?)-->|"
                  r"(?<!`)<!-- doc: (?P<key>.*?) -->(?P<body>.*?)<!-- /doc -->", re.S)
EXIT = re.compile(r"\s*->\s*exit\s+(\d+)\s*$")


class DocError(Exception):
    pass


class Session:
    """One page: a scratch folder, the commands run so far, their cached outputs."""

    def __init__(self, page: str):
        self.page = page
        self.dir = tempfile.mkdtemp(prefix="acl-docs-")
        for name in ("examples", "samples"):
            if (ROOT / name).is_dir():
                shutil.copytree(ROOT / name, Path(self.dir) / name)
        self.cache: dict[str, tuple[int, str, str]] = {}
        self.ns: dict | None = None

    def close(self) -> None:
        shutil.rmtree(self.dir, ignore_errors=True)

    def acl(self, cmdline: str, want: int | None = 0) -> tuple[str, str]:
        """Run ``acl ARGS`` in the scratch folder: (stdout, stdout+stderr interleaved)."""
        argv = shlex.split(cmdline)
        if argv and argv[0] == "acl":
            argv = argv[1:]
        if cmdline not in self.cache:
            from acl.cli import main

            out, both = io.StringIO(), io.StringIO()

            class Tee(io.StringIO):
                def write(self, s):
                    out.write(s)
                    return both.write(s)

            env_cols = os.environ.pop("COLUMNS", None)
            try:
                with contextlib.chdir(self.dir), contextlib.redirect_stdout(Tee()), \
                        contextlib.redirect_stderr(both):
                    try:
                        code = main(argv)
                    except SystemExit as exc:
                        code = exc.code if isinstance(exc.code, int) else 2
            finally:
                if env_cols is not None:
                    os.environ["COLUMNS"] = env_cols
            self.cache[cmdline] = (code, out.getvalue(), both.getvalue())
        code, out, both = self.cache[cmdline]
        if want is not None and code != want:
            raise DocError(f"{self.page}: `acl {' '.join(argv)}` exited {code}, the page expects {want}:\n{both}")
        return out, both

    def namespace(self) -> dict:
        """The page's Python namespace, shared by its doc-py, `=` and doctest markers."""
        if self.ns is None:
            self.ns = self._namespace()
        return self.ns

    def run_py(self, code: str) -> None:
        import textwrap

        with contextlib.chdir(self.dir):
            exec(compile(textwrap.dedent(code).strip() + "\n", f"<{self.page}>", "exec"), self.namespace())

    def _namespace(self) -> dict:
        import acl

        def json_of(args: str):
            return json.loads(self.acl(f"{args} --output-format json", want=None)[0])

        def out_of(args: str) -> str:
            return self.acl(args)[0]

        def ci(entry: dict, scale: float = 1e6, fmt: str = ".1f", unit: str = "um") -> str:
            v, (lo, hi) = entry["value"] * scale, [x * scale for x in entry["ci95"]]
            return f"{v:{fmt}} {unit} [{lo:{fmt}}, {hi:{fmt}}]"

        def block(obj, lang: str = "json") -> str:
            text = json.dumps(_rounded(obj), indent=2) if lang == "json" else str(obj)
            return f"\n```{lang}\n{text.rstrip()}\n```\n"

        return {"acl": acl, "json_of": json_of, "out_of": out_of, "ci": ci, "block": block}

    def evaluate(self, expr: str) -> str:
        with contextlib.chdir(self.dir):
            return str(eval(expr, self.namespace()))    # the repository's own pages only

    def doctest(self, body: str) -> str:
        ns = self.namespace()
        lines, out, i = body.split("\n"), [], 0
        with contextlib.chdir(self.dir):
            while i < len(lines):
                line = lines[i]
                if not line.startswith(">>> "):
                    out.append(line)
                    i += 1
                    continue
                src = [line[4:]]
                out.append(line)
                i += 1
                while i < len(lines) and lines[i].startswith("... "):
                    src.append(lines[i][4:])
                    out.append(lines[i])
                    i += 1
                while i < len(lines) and lines[i].strip() and not lines[i].startswith(">>> ") \
                        and not lines[i].startswith("```"):
                    i += 1                              # the previous output of this statement
                buf = io.StringIO()
                with contextlib.redirect_stdout(buf):
                    exec(compile("\n".join(src) + "\n", f"<{self.page}>", "single"), ns)
                printed = buf.getvalue().rstrip("\n")
                if printed:
                    out.extend(printed.split("\n"))
        return "\n".join(out)


def _rounded(obj, digits: int = 6):
    """Floats to ``digits`` significant digits (the last digits of a solver's result are noise)."""
    if isinstance(obj, float):
        return float(f"{obj:.{digits}g}")
    if isinstance(obj, dict):
        return {k: _rounded(v, digits) for k, v in obj.items()}
    if isinstance(obj, list):
        return [_rounded(v, digits) for v in obj]
    return obj


NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")
REL_TOL = 2e-3      # numbers agree to 0.2 % (one unit in the 4th digit; BLAS and solver versions differ)
NOISE = 1e-20       # SI magnitudes below this (solver residuals) are numerical noise


def same(old: str, new: str) -> bool:
    """The texts are equal but for numbers that agree within REL_TOL (or are both below NOISE)."""
    if old == new:
        return True
    if NUMBER.split(old) != NUMBER.split(new):
        return False
    for a, b in zip(map(float, NUMBER.findall(old)), map(float, NUMBER.findall(new))):
        if not (abs(a - b) <= REL_TOL * max(abs(a), abs(b)) or max(abs(a), abs(b)) < NOISE):
            return False
    return True


def render(page: str, text: str) -> str:
    """The page with every marked part regenerated."""
    session = Session(page)
    try:
        pieces, pos = [], 0
        for m in MARK.finditer(text):
            pieces.append(text[pos:m.start()])
            pos = m.end()
            if m.group("run") is not None:
                cmd, want = _exit(m.group("run"))
                session.acl(cmd, want)
                pieces.append(m.group(0))
                continue
            if m.group("py") is not None:
                session.run_py(m.group("py"))
                pieces.append(m.group(0))
                continue
            key, body = m.group("key").strip(), m.group("body")
            if key.startswith("$"):
                cmd, want = _exit(key[1:])
                both = session.acl(cmd, want)[1]
                new = "\n```text\n" + both.rstrip("\n") + "\n```\n"
            elif key.startswith("="):
                new = session.evaluate(key[1:].strip())
            elif key == "doctest":
                new = session.doctest(body)
            else:
                raise DocError(f"{page}: unknown doc marker `{key}`")
            pieces.append(f"<!-- doc: {m.group('key')} -->{new}<!-- /doc -->")
        pieces.append(text[pos:])
        return "".join(pieces)
    finally:
        session.close()


def _exit(cmd: str) -> tuple[str, int]:
    m = EXIT.search(cmd)
    return (cmd[:m.start()], int(m.group(1))) if m else (cmd, 0)


def stale(pages=None, exact: bool = False) -> dict[str, tuple[str, str]]:
    """{page: (unified diff, fresh text)} of the pages whose marked parts no longer match a fresh run
    (``exact``: any difference, also in the last digits)."""
    out = {}
    for page in pages or PAGES:
        old = (ROOT / page).read_text(encoding="utf-8")
        if "<!-- doc" not in old:
            continue
        new = render(page, old)
        if new != old if exact else not same(old, new):
            diff = "".join(difflib.unified_diff(old.splitlines(True), new.splitlines(True), page, page + " (fresh run)"))
            out[page] = (diff, new)
    return out


def main(argv: list[str]) -> int:
    update = "--update" in argv
    pages = [a for a in argv if not a.startswith("--")] or None
    sys.path.insert(0, str(ROOT))
    try:
        diffs = stale(pages, exact=update)
    except DocError as exc:
        sys.stderr.write(f"docs_sync: {exc}\n")
        return 2
    for page, (diff, new) in diffs.items():
        if update:
            (ROOT / page).write_text(new, encoding="utf-8")
            print(f"updated {page}")
        else:
            sys.stdout.write(diff)
    if not diffs:
        print("docs are up to date")
    return 1 if diffs and not update else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
