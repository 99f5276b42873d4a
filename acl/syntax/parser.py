"""Source text -> syntax tree with spans (lark LALR), with per-statement error recovery."""
from __future__ import annotations

import bisect
import contextlib
import functools
import gc
import re
import sys
from importlib import resources

from lark import Lark, Token, Tree
from lark.exceptions import UnexpectedCharacters, UnexpectedEOF, UnexpectedInput, UnexpectedToken, VisitError

from acl.diagnostics import Diagnostic, DiagnosticError, Span, error
from acl.syntax import ast as A

MAX_SOURCE_BYTES = 2_000_000
MAX_NESTING = 64
MAX_TREE_DEPTH = 200      # syntax tree levels: keeps every later tree walk far from Python's recursion limit

# Words shown to users instead of terminal names.
_TERMINAL_WORDS = {
    "NAME": "a name", "QUANTITY": "a quantity with a unit", "NUMBER": "a number",
    "STRING": "a quoted string", "DIRECTION": "a direction such as +x", "_NL": "end of line",
    "$END": "end of file", "CMP": "a comparison (>=, <=, >, <)", "RANGE": "`..`", "_PM": "`+-`",
}


# Words from other languages for program steps -> the acl step.
_STEP_WORDS = {"wait": "pause", "sleep": "pause", "delay": "pause", "idle": "pause", "ramp": "sweep",
               "play": "drive", "tone": "drive", "move": "follow", "trace": "follow", "toggle": "switch"}


def _underflows(text: str) -> bool:
    """True when a literal with a nonzero digit is below the smallest normal 64-bit float (it would read as 0 or
    lose its precision): `1e-400` is not zero."""
    v = abs(float(text))
    return v < sys.float_info.min and re.search(r"[1-9]", re.split(r"[eE]", text)[0]) is not None


class _ParenNewlines:
    """Post-lexer: newlines inside ( ) and [ ] are not statement ends."""

    always_accept = ("_NL",)

    def process(self, stream):
        depth = 0
        for tok in stream:
            if tok.type == "_NL":
                if depth > 0:
                    continue
            elif tok.value in ("(", "["):
                depth += 1
            elif tok.value in (")", "]"):
                depth = max(0, depth - 1)
            yield tok


@functools.lru_cache(maxsize=1)
def lark_parser() -> Lark:
    text = resources.files("acl.syntax").joinpath("grammar.lark").read_text(encoding="utf-8")
    return Lark(text, parser="lalr", start=["start", "drive_only"], propagate_positions=True,
                maybe_placeholders=True, postlex=_ParenNewlines(), cache=_cache_path(text))


def _cache_path(grammar: str):
    """Where lark may keep the compiled grammar, or False (no cache).

    lark's cache is a pickle, and loading a pickle runs code: it is kept only in a folder this user
    owns and nobody else may write (``$ACL_CACHE_DIR``, ``~/.cache/acl``, else a private folder in
    the temporary directory), never as a guessable name in a shared /tmp that another user could
    plant first.
    """
    import hashlib
    import os
    import tempfile

    try:
        import lark

        from acl import __version__

        uid = os.getuid() if hasattr(os, "getuid") else None
        folders = [os.environ.get("ACL_CACHE_DIR") or os.path.join(os.path.expanduser("~"), ".cache", "acl"),
                   os.path.join(tempfile.gettempdir(), f"acl-cache-{uid if uid is not None else 'user'}")]
        for folder in folders:
            if _private(folder, uid, make=True):
                digest = hashlib.sha256(grammar.encode("utf-8")).hexdigest()[:16]   # worktrees differ
                path = os.path.join(folder, f"grammar-{__version__}-lark{lark.__version__}-{digest}.cache")
                if not os.path.lexists(path) or _private(path, uid, make=False):
                    return path
    except Exception:  # pragma: no cover - the cache is an optimisation only
        pass
    return False


def _private(path: str, uid, make: bool) -> bool:
    """Whether ``path`` (created as a 0700 folder if ``make``) is this user's and not writable by others."""
    import os
    import stat

    try:
        if make:
            os.makedirs(path, mode=0o700, exist_ok=True)
        st = os.lstat(path)
    except OSError:
        return False
    if stat.S_ISLNK(st.st_mode) or (uid is not None and st.st_uid != uid):
        return False
    return not st.st_mode & (stat.S_IWGRP | stat.S_IWOTH)


def _terminal_word(name: str) -> str:
    if name in _TERMINAL_WORDS:
        return _TERMINAL_WORDS[name]
    try:
        for t in lark_parser().terminals:
            if t.name == name and t.pattern.type == "str":
                return f"`{t.pattern.value}`"
    except Exception:  # pragma: no cover
        pass
    return name.lower()


def _span(file: str, meta_or_tok) -> Span:
    if isinstance(meta_or_tok, Token):
        return Span(file=file, line=meta_or_tok.line, column=meta_or_tok.column,
                    end_line=meta_or_tok.end_line, end_column=meta_or_tok.end_column)
    m = meta_or_tok
    if getattr(m, "empty", True):
        return Span(file=file, line=1, column=1)
    return Span(file=file, line=m.line, column=m.column, end_line=m.end_line, end_column=m.end_column)


_TOKEN_NODES = (A.Qty, A.Num, A.Str, A.Dir)     # nodes built from one token (no tree of their own)


class _Builder:
    """lark tree -> acl.syntax.ast nodes.

    Every rule method takes ``(meta, children)``; token methods (named after the terminal) take the
    token.  The walk is iterative (a design nested deeper than :data:`MAX_TREE_DEPTH` is refused with
    a located E104), and rule methods are looked up once per builder, not once per node.
    """

    def transform(self, root):
        rules, tokens = self._dispatch()
        frames = [(root, iter(root.children), [])]
        while True:
            tree, it, acc = frames[-1]
            for c in it:
                if type(c) is Tree:
                    if len(frames) >= MAX_TREE_DEPTH:
                        raise DiagnosticError([error(
                            "E104", f"expression or block nested deeper than {MAX_TREE_DEPTH} levels", self._s(c.meta),
                            "split it into parameters (`param part = ...`); a long sum or chain of `-` counts one level per term")])
                    frames.append((c, iter(c.children), []))
                    break
                if type(c) is Token:
                    f = tokens.get(c.type)
                    acc.append(f(c) if f is not None else c)
                else:
                    acc.append(c)
            else:
                frames.pop()
                f = rules.get(tree.data)
                try:
                    value = f(tree.meta, acc) if f is not None else Tree(tree.data, acc, tree.meta)
                except DiagnosticError:
                    raise
                except Exception as e:  # same contract as lark's transformers: callers see VisitError
                    raise VisitError(tree.data, tree, e) from e
                if not frames:
                    return value
                frames[-1][2].append(value)

    def _dispatch(self):
        cls = type(self)
        names = cls.__dict__.get("_NAMES")
        if names is None:
            names = [n for n in dir(cls) if not n.startswith("_") and n != "transform" and callable(getattr(cls, n))]
            cls._NAMES = names
        rules = {n: getattr(self, n) for n in names if not n.isupper()}
        tokens = {n: getattr(self, n) for n in names if n.isupper()}
        return rules, tokens

    def __init__(self, file: str, source: str):
        self.file = file
        self.source = source
        self._lines: list[str] | None = None   # split once, on first need
        self._starts: list[int] | None = None  # offset of each line's start (chains with parentheses)

    def _s(self, x) -> Span:
        return _span(self.file, x)

    # ---- expressions (literals arrive as tokens: no tree node of their own)
    def QUANTITY(self, tok):
        m = re.match(r"(\d+\.\d+|\d+\.(?!\.)|\.\d+|\d+)([eE][+-]?\d+)?", tok.value)
        num = m.group(0)
        return A.Qty(self._s(tok), float(num), tok.value[len(num):].strip(), _underflows(num))

    def NUMBER(self, tok):
        return A.Num(self._s(tok), float(tok.value), _underflows(tok.value))

    def STRING(self, tok):
        return A.Str(self._s(tok), tok.value[1:-1])

    def DIRECTION(self, tok):
        return A.Dir(self._s(tok), 1 if tok.value[0] == "+" else -1, tok.value[1])

    def ref(self, meta, children):
        return A.Ref(self._s(meta), tuple(str(c) for c in children))

    def call(self, meta, children):
        name = str(children[0])
        args, kwargs = [], []
        for c in children[1:]:
            if c is None:
                continue
            if isinstance(c, tuple):
                kwargs.append(c)
            else:
                args.append(c)
        return A.Call(self._s(meta), name, tuple(args), tuple(kwargs))

    def kwarg(self, meta, children):
        return (str(children[0]), children[1])

    def vector(self, meta, children):
        return A.Vec(self._s(meta), tuple(children))

    def list(self, meta, children):
        return A.ListExpr(self._s(meta), tuple(c for c in children if c is not None))

    def _bin(op):  # noqa: N805
        def f(self, meta, children):
            return A.BinOp(self._s(meta), op, children[0], children[1])
        return f

    pow = _bin("^")

    def _chain(self, meta, children):
        """``t0 op1 t1 op2 t2 ...`` (a flat chain: one tree level however long, so a sum of 1,000 terms is
        not "nested") -> BinOp nodes folded left to right, with the spans a left-nested parse gave them:
        each from the chain's first token to its right operand's last, a closing parenthesis included."""
        out = children[0]
        whole = self._s(meta)
        last = len(children) - 2
        for i in range(1, len(children), 2):
            right = children[i + 1]
            if i == last:
                end_line, end_column = whole.end_line, whole.end_column
            elif type(right) in _TOKEN_NODES:        # `(4)`: a token's parentheses never counted (lark's inlining)
                end_line, end_column = right.span.end_line, right.span.end_column
            else:
                end_line, end_column = self._group_end(right.span, children[i + 2])
            span = Span(file=whole.file, line=whole.line, column=whole.column, end_line=end_line, end_column=end_column)
            out = A.BinOp(span, str(children[i]), out, right)
        return out

    def _group_end(self, span: Span, op: Token) -> tuple[int, int]:
        """End (line, column) of a chain's term as lark's positions counted it: its span's end, after the
        parentheses that wrap the whole term (they close between it and the next operator ``op``)."""
        if self._starts is None:
            self._starts = [0] + [m.end() for m in re.finditer("\n", self.source)]
        starts, src = self._starts, self.source
        begin = starts[span.line - 1] + span.column - 1
        finish = starts[span.end_line - 1] + span.end_column - 1
        opened = 0                       # `(` between the previous operator and the term's first token
        i = begin - 1
        while i >= 0:
            if src[i] in "( \t\f\r\n\\":
                opened += src[i] == "("
                i -= 1
                continue
            hash_ = src.find("#", starts[bisect.bisect_right(starts, i) - 1], i + 1)
            if hash_ < 0:                # the previous operator (a comment on the line is skipped)
                break
            i = hash_ - 1
        balance = low = 0                # `)` inside the term closing a `(` opened before it
        i = begin
        while i < finish:
            c = src[i]
            if c == "#":
                i = src.find("\n", i, finish) if "\n" in src[i:finish] else finish
                continue
            if c == '"':
                q = src.find('"', i + 1, finish)
                i = finish if q < 0 else q + 1
                continue
            balance += (c == "(") - (c == ")")
            low = min(low, balance)
            i += 1
        # parens wrap the whole term when some opened before it stay open through it; the gap after it
        # closes first those opened inside it and left open (`(1 + (4))`: the span ends at `4`), then those
        wraps = opened + balance if opened + low > 0 else 0
        line, col = span.end_line, span.end_column
        i = finish
        while wraps > 0 and i < op.start_pos:
            c = src[i]
            if c == "#":
                nl = src.find("\n", i, op.start_pos)
                i = op.start_pos if nl < 0 else nl
                continue
            if c == ")":
                wraps -= 1
                line = bisect.bisect_right(starts, i)
                col = i - starts[line - 1] + 2
            i += 1
        return line, col

    sum = _chain
    product = _chain

    def range(self, meta, children):
        return A.Range(self._s(meta), children[0], children[2])

    def neg(self, meta, children):
        return A.Neg(self._s(meta), children[0])

    # ---- statements
    def dotted(self, meta, children):
        return tuple(str(c) for c in children)

    def import_module(self, meta, children):
        path, alias = children
        return A.Import(path, None, str(alias) if alias else None, self._s(meta))

    def import_file(self, meta, children):
        return A.Import(None, children[0].value, str(children[1]), self._s(meta))   # a Str node

    def extends_stmt(self, meta, children):
        return A.Extends(children[0].value, self._s(meta))   # a Str node

    def free_clause(self, meta, children):
        rng = children[0]
        if isinstance(rng, A.Range):
            return ("free", rng.lower, rng.upper)
        return ("free", rng, None) if rng is not None else ("free", None, None)

    def param_stmt(self, meta, children):
        name, value, stddev, free = children
        lo = hi = None
        if free:
            _, lo, hi = free
        return A.ParamDecl(str(name), value, free is not None, lo, hi, self._s(meta), stddev)

    def uncertainty_entry(self, meta, children):
        return A.UncertaintyEntry(children[0], children[1], self._s(meta))

    def uncertainty_stmt(self, meta, children):
        return A.UncertaintyDecl(tuple(c for c in children if c is not None), self._s(meta))

    def use_stmt(self, meta, children):
        return A.Use(str(children[0]), children[1], self._s(meta))

    def mount_stmt(self, meta, children):
        return A.MountStmt(children[0], children[1], self._s(meta))

    def fix_stmt(self, meta, children):
        return A.FixStmt(children[0], self._s(meta))

    def link_stmt(self, meta, children):
        return A.LinkStmt(children[0], children[1], children[2], self._s(meta))

    def observe_stmt(self, meta, children):
        return A.ObserveDecl(str(children[0]), children[1], self._s(meta))

    def _text(self, meta) -> str:
        if self._lines is None:
            self._lines = self.source.splitlines()
        lines = self._lines
        if getattr(meta, "empty", True) or meta.line > len(lines):
            return ""
        if meta.line == meta.end_line:
            return lines[meta.line - 1][meta.column - 1:meta.end_column - 1].strip()
        return lines[meta.line - 1][meta.column - 1:].strip()

    def require_cmp(self, meta, children):
        call, op, value = children
        return A.RequireDecl(call, str(op), value, None, self._text(meta), self._s(meta))

    def require_in(self, meta, children):
        call, rng = children
        if isinstance(rng, A.Range):
            return A.RequireDecl(call, "in", rng.lower, rng.upper, self._text(meta), self._s(meta))
        return A.RequireDecl(call, "in", rng, None, self._text(meta), self._s(meta))

    def decl(self, meta, children):
        kind, name, like, block = children
        return A.Block(str(kind), str(name), block, self._s(meta), self._s(kind), like)

    def block(self, meta, children):
        return tuple(c for c in children if c is not None)

    def assign(self, meta, children):
        return A.Assign(str(children[0]), children[1], self._s(meta), self._s(children[0]))

    def sub_block(self, meta, children):
        kind, name, block = children
        return A.Block(str(kind), str(name) if name else None, block, self._s(meta), self._s(kind))

    # ---- programs
    def program(self, meta, children):
        return A.ProgramDecl(str(children[0]), tuple(children[1:]), self._s(meta))

    def tone(self, meta, children):
        f, v, ph = children
        return A.ToneExpr(f, v, ph, self._s(meta))

    def drive(self, meta, children):
        return tuple(children)

    def drive_only(self, meta, children):
        return children[0]

    def options(self, meta, children):
        kw = {}
        for key, val in children:
            kw[key] = val
        return A.Options(**kw)

    def opt_limit(self, meta, c):
        return ("limit", c[0])

    def opt_slew(self, meta, c):
        return ("slew", c[0])

    def opt_margin(self, meta, c):
        return ("margin", c[0])

    def opt_using(self, meta, c):
        return ("using", c[0])

    def drive_step(self, meta, children):
        tones, dur, opts = children
        return A.DriveS(tones, dur, opts, self._s(meta))

    def sweep_step(self, meta, children):
        f0, f1, amp, dur, log, opts = children
        return A.SweepS(f0, f1, amp, dur, log is not None, opts, self._s(meta))

    def pause_step(self, meta, children):
        return A.PauseS(children[0], self._s(meta))

    def within(self, meta, c):
        return ("in", c[0])

    def at_speed(self, meta, c):
        return ("at", c[0])

    def follow_step(self, meta, children):
        cap, path, (how, val), opts = children
        return A.FollowS(cap, path, val if how == "in" else None, val if how == "at" else None, opts,
                         self._s(meta))

    def switch_step(self, meta, children):
        latch, state, opts = children
        return A.SwitchS(latch, str(state), self._s(state), opts, self._s(meta))

    def hold_above(self, meta, children):
        call, bound, dur, opts = children
        return A.HoldS(call, "above", bound, dur, opts, self._s(meta))

    def hold_cross(self, meta, children):
        call, dur, opts = children
        return A.HoldS(call, "cross", None, dur, opts, self._s(meta))

    def start(self, meta, children):
        return tuple(children)


@contextlib.contextmanager
def paused_gc():
    """Pause the cyclic garbage collector while a design is built.

    The front end allocates ~10 objects per source token and frees none of them until the end; the
    collector's passes over that growing heap cost more than the parse itself on large designs
    (benchmarks/check.py). Reference counting still frees everything; a collection runs after.
    """
    was = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was:
            gc.enable()


# ---------------------------------------------------------------------------------------------
# Entry points
# ---------------------------------------------------------------------------------------------

def parse_module(source: str, file: str = "<string>") -> A.Module:
    """Parse a whole file. Raises DiagnosticError with one diagnostic per broken statement."""
    if source.startswith("\ufeff"):   # a UTF-8 byte-order mark (Windows editors) is not part of the text
        source = source[1:]
    with paused_gc():
        return _parse_module(source, file)


def parse_module_tree(source: str, file: str = "<string>") -> tuple[A.Module, Tree]:
    """:func:`parse_module` and the lark tree it was built from (the formatter reads its tokens),
    from one parse. Raises DiagnosticError as parse_module does."""
    if source.startswith("\ufeff"):
        source = source[1:]
    with paused_gc():
        got = _parse_module(source, file, keep_tree=True)
    return got


def _parse_module(source: str, file: str, keep_tree: bool = False):
    check_limits(source, file)
    text = source if source.endswith("\n") else source + "\n"
    try:
        tree = lark_parser().parse(text, start="start")
        stmts = build_module(tree, file, source)
        module = A.Module(file, stmts, source)
        return (module, tree) if keep_tree else module
    except UnexpectedInput:
        pass
    # Recovery: parse each top-level statement on its own, keeping line numbers.
    diags: list[Diagnostic] = []
    lines = text.split("\n")
    for start, end in statement_chunks(lines):
        # each statement alone, without padding it to its line (that made recovery quadratic):
        # the error's line is shifted back by `start` below
        chunk = "\n".join(lines[start:end]) + "\n"
        try:
            lark_parser().parse(chunk, start="start")
        except UnexpectedInput as exc:
            d = _syntax_diagnostic(exc, file, lines, eof_line=_last_line(lines, start, end), line_offset=start)
            opened = _unclosed_brace(lines, start, end) if _at_end(exc) else None
            if opened is not None:  # point at the block that never closes, not at where the text ran out
                ln, col = opened
                d = error("E112", "this block is never closed", Span(file=file, line=ln, column=col, end_line=ln, end_column=col + 1),
                          f"add the missing `}}` (the statement runs to line {_last_line(lines, start, end)})")
            diags.append(d)
    if not diags:  # the chunker disagreed with the parser; report the whole-file error
        try:
            lark_parser().parse(text, start="start")
        except UnexpectedInput as exc:
            diags.append(_syntax_diagnostic(exc, file, lines))
    raise DiagnosticError(diags)


def parse_drive(text: str, file: str = "<drive>", line: int = 1, column: int = 1) -> tuple[A.ToneExpr, ...]:
    """Parse a drive expression on its own (`125 kHz @ 6 V + 85 kHz @ 2 V`), as data files use."""
    if len(text) > 10_000:
        raise DiagnosticError([error("E101", "drive expression too long", Span(file=file, line=line, column=column))])
    try:
        tree = lark_parser().parse(text, start="drive_only")
    except UnexpectedInput as exc:
        d = _syntax_diagnostic(exc, file, text.split("\n"))
        span = Span(file=file, line=line, column=column + (d.span.column - 1 if d.span else 0))
        raise DiagnosticError([Diagnostic(d.code, d.severity, f"in drive `{text.strip()}`: {d.message}", span, d.hint or "a drive looks like `125 kHz @ 6 V` or `85 kHz @ 8 V + 125 kHz @ 4 V`")])
    try:
        tones = _Builder(file, text).transform(tree)
    except DiagnosticError as exc:   # too deep: place it in the cell, as syntax errors are
        raise DiagnosticError([Diagnostic(d.code, d.severity, f"in drive `{text.strip()[:60]}`: {d.message}",
                                          Span(file=file, line=line, column=column + (d.span.column - 1 if d.span else 0)),
                                          d.hint) for d in exc.diagnostics]) from None
    if line != 1 or column != 1:  # shift spans to where the drive sits (a CSV cell)
        tones = tuple(_shift_tone(t, line, column) for t in tones)
    return tones


def _shift_tone(t: A.ToneExpr, line: int, column: int) -> A.ToneExpr:
    s = Span(file=t.span.file, line=line, column=column + t.span.column - 1)
    return A.ToneExpr(t.frequency, t.amplitude, t.phase, s)


def build_module(tree, file: str, source: str) -> tuple:
    try:
        return _Builder(file, source).transform(tree)
    except VisitError as exc:  # pragma: no cover - a builder bug must still not leak a traceback
        raise DiagnosticError([error("E100", f"internal parser error: {exc.orig_exc}", Span(file=file, line=1, column=1))])


def check_limits(source: str, file: str) -> None:
    if len(source.encode("utf-8", errors="replace")) > MAX_SOURCE_BYTES:
        raise DiagnosticError([error("E102", f"file larger than {MAX_SOURCE_BYTES // 1_000_000} MB",
                                     Span(file=file, line=1, column=1), "split the design into imported files")])
    if "\x00" in source:
        i = source.index("\x00")
        line = source.count("\n", 0, i) + 1
        col = i - (source.rfind("\n", 0, i) + 1) + 1
        raise DiagnosticError([error("E103", "file contains a NUL byte: not a text design",
                                     Span(file=file, line=line, column=col))])
    depth = 0
    line, col = 1, 0
    in_str = in_comment = False
    for ch in source:
        col += 1
        if ch == "\n":
            line, col, in_comment, in_str = line + 1, 0, False, False
            continue
        if in_comment:
            continue
        if ch == '"':
            in_str = not in_str
        elif in_str:
            continue
        elif ch == "#":
            in_comment = True
        elif ch in "([{":
            depth += 1
            if depth > MAX_NESTING:
                raise DiagnosticError([error("E104", f"nesting deeper than {MAX_NESTING} levels",
                                             Span(file=file, line=line, column=col), "simplify the expression")])
        elif ch in ")]}":
            depth -= 1


#: a top-level keyword at column 0: while brackets are open it starts a new statement (missing brace)
TOP_KEYWORD = re.compile(r"(import|extends|param|uncertainty|program|mount|fix|link|observe|require|use|capsule|"
                         r"beam|medium|material|transducer|generator|amplifier|latch|spring|truss|anchor|effect)\b")


def statement_chunks(lines: list[str], delta=None):
    """Yield (start, end) line ranges of top-level statements, tracking bracket depth.

    ``delta`` (default :func:`depth_delta`) gives a line's change of bracket depth; the editor
    passes a memoised one.  Used by error recovery here and by the language server's incremental parse.
    """
    delta = delta or depth_delta
    i, n = 0, len(lines)
    while i < n:
        stripped = lines[i].strip()
        if not stripped or stripped.startswith("#"):
            i += 1
            continue
        start, depth = i, 0
        while i < n:
            depth += delta(lines[i])
            i += 1
            if depth <= 0 and not lines[i - 1].rstrip().endswith("\\"):
                break
            if depth > 0 and i < n and TOP_KEYWORD.match(lines[i]):
                break
        yield start, i


def _code_chars(line: str):
    """(column index, character) of a line's code: outside strings, before a comment."""
    in_str = False
    for j, ch in enumerate(line):
        if ch == '"':
            in_str = not in_str
        elif in_str:
            continue
        elif ch == "#":
            return
        else:
            yield j, ch


def depth_delta(line: str) -> int:
    return sum((ch in "([{") - (ch in ")]}") for _, ch in _code_chars(line))


def _at_end(exc) -> bool:
    return isinstance(exc, UnexpectedEOF) or (isinstance(exc, UnexpectedToken) and exc.token.type == "$END")


def _unclosed_brace(lines: list[str], start: int, end: int) -> tuple[int, int] | None:
    """(line, column) of the last `{` in lines[start:end] left open, ignoring strings and comments."""
    stack = []
    for i in range(start, min(end, len(lines))):
        for j, ch in _code_chars(lines[i]):
            if ch == "{":
                stack.append((i + 1, j + 1))
            elif ch == "}" and stack:
                stack.pop()
    return stack[-1] if stack else None


def _last_line(lines: list[str], start: int, end: int) -> int:
    for i in range(min(end, len(lines)) - 1, start - 1, -1):
        if lines[i].strip():
            return i + 1
    return start + 1


def _syntax_diagnostic(exc: UnexpectedInput, file: str, lines: list[str], eof_line: int | None = None,
                       line_offset: int = 0) -> Diagnostic:
    line = getattr(exc, "line", 1) or 1
    col = getattr(exc, "column", 1) or 1
    if line < 1:
        line, col = max(1, len(lines) - 1), 1
    else:
        line += line_offset
    span = Span(file=file, line=line, column=col, end_line=line, end_column=col + 1)
    if isinstance(exc, UnexpectedCharacters):
        ch = lines[line - 1][col - 1] if line - 1 < len(lines) and col - 1 < len(lines[line - 1]) else "?"
        hint = None
        if ch == "'":
            hint = 'strings use double quotes: "EPFL"'
        elif ch == "=" and col > 1 and lines[line - 1][col - 2] in "=!":
            hint = "compare with >=, <=, > or <"
        elif ch.isalpha() and not ch.isascii():      # `капсула`, `délai`, or a Cyrillic `а` that looks like `a`
            import unicodedata

            hint = (f"names are ASCII letters, digits and _ ({ch!r} is U+{ord(ch):04X} "
                    f"{unicodedata.name(ch, 'a non-ASCII letter')})")
        return error("E110", f"unexpected character {ch!r}", span, hint)
    if isinstance(exc, UnexpectedToken):
        tok = exc.token
        expected = sorted({_terminal_word(t) for t in exc.expected if not t.startswith("__")})
        got = "end of file" if tok.type == "$END" else ("end of line" if tok.type == "_NL" else f"`{tok.value}`")
        if tok.type == "$END":
            ln = eof_line or _last_line(lines, 0, len(lines))
            span = Span(file=file, line=ln, column=max(1, len(lines[ln - 1].rstrip()) if ln - 1 < len(lines) else 1))
        hint = None
        word = tok.value if tok.type not in ("$END", "_NL") else None
        text = "\n".join(lines)
        if tok.type == "$END" and "`)`" in expected and text.count("(") > text.count(")"):
            hint = "a `(` is missing its closing `)`"
        elif "`}`" in expected and tok.type in ("$END",):
            hint = "a block is missing its closing `}`"
        elif word in _STEP_WORDS and "`pause`" in expected:
            hint = f"did you mean `{_STEP_WORDS[word]}`?"
        elif word == "to" and "`..`" in expected:
            hint = "a range is written `lo .. hi`, e.g. `40 kHz .. 200 kHz`"
        elif word in ("tones", "tone", "with", "freqs", "frequencies") and "`using`" in expected:
            hint = "did you mean `using`? (`, using [85 kHz, 125 kHz]`)"
        elif word and tok.type == "NAME":   # a misspelt keyword
            from acl.diagnostics import suggest

            keywords = [e.strip("`") for e in expected if e.startswith("`") and e.strip("`").isalpha()]
            hint = suggest(word, keywords)
        elif tok.type == "NUMBER" and "a quantity with a unit" not in expected:
            hint = None
        elif tok.type == "_NL" and "`=`" in expected:
            hint = "an entry is written `key = value`"
        exp = ", ".join(expected[:8]) + (" ..." if len(expected) > 8 else "")
        return error("E111", f"unexpected {got}; expected {exp}", span, hint)
    if isinstance(exc, UnexpectedEOF):
        return error("E112", "unexpected end of file", span, "a block is missing its closing `}`")
    return error("E111", str(exc).splitlines()[0], span)
