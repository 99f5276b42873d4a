"""Syntax tree of an acl file: small frozen dataclasses, each node with its source span."""
from __future__ import annotations

from dataclasses import dataclass, field

from acl.diagnostics import Span


# ---- expressions ------------------------------------------------------------------------------

@dataclass(frozen=True)
class Expr:
    span: Span


@dataclass(frozen=True)
class Num(Expr):
    value: float
    underflow: bool = False     # a literal with a nonzero digit that a 64-bit float rounds to 0 or a subnormal


@dataclass(frozen=True)
class Qty(Expr):
    value: float
    unit: str
    underflow: bool = False     # as Num.underflow, for the number in front of the unit


@dataclass(frozen=True)
class Str(Expr):
    value: str


@dataclass(frozen=True)
class Dir(Expr):
    sign: int
    axis: str          # "x" | "y" | "z"


@dataclass(frozen=True)
class Ref(Expr):
    parts: tuple[str, ...]

    @property
    def dotted(self) -> str:
        return ".".join(self.parts)


@dataclass(frozen=True)
class Call(Expr):
    name: str
    args: tuple[Expr, ...]
    kwargs: tuple[tuple[str, Expr], ...] = ()

    def kw(self, key: str) -> Expr | None:
        for k, v in self.kwargs:
            if k == key:
                return v
        return None


@dataclass(frozen=True)
class Vec(Expr):
    items: tuple[Expr, ...]


@dataclass(frozen=True)
class ListExpr(Expr):
    items: tuple[Expr, ...]


@dataclass(frozen=True)
class BinOp(Expr):
    op: str            # + - * / ^
    left: Expr
    right: Expr


@dataclass(frozen=True)
class Range(Expr):
    lower: Expr
    upper: Expr


@dataclass(frozen=True)
class Neg(Expr):
    operand: Expr


# ---- declarations -----------------------------------------------------------------------------

@dataclass(frozen=True)
class Assign:
    key: str
    value: Expr
    span: Span
    key_span: Span


@dataclass(frozen=True)
class Block:
    """A generic `KIND [NAME] { entries }` block (top level or nested)."""

    kind: str
    name: str | None
    entries: tuple  # of Assign | Block
    span: Span
    kind_span: Span
    like: Ref | None = None

    def assigns(self) -> list[Assign]:
        return [e for e in self.entries if isinstance(e, Assign)]

    def blocks(self) -> list["Block"]:
        return [e for e in self.entries if isinstance(e, Block)]


@dataclass(frozen=True)
class Import:
    module: tuple[str, ...] | None   # dotted stdlib/sibling module path
    file: str | None                 # quoted file path
    alias: str | None
    span: Span


@dataclass(frozen=True)
class Extends:
    file: str
    span: Span


@dataclass(frozen=True)
class ParamDecl:
    name: str
    value: Expr
    free: bool
    lower: Expr | None
    upper: Expr | None
    span: Span
    stddev: Expr | None = None       # `param x = v +- s`: the standard deviation


@dataclass(frozen=True)
class UncertaintyEntry:
    """One `KEY(args) = value` line of an `uncertainty { ... }` block (`lognormal(a, b)` has no value: None)."""

    key: Call
    value: Expr | None
    span: Span


@dataclass(frozen=True)
class UncertaintyDecl:
    """`uncertainty { correlation(a, b) = r, covered(voltage) = lo .. hi }`."""

    entries: tuple[UncertaintyEntry, ...]
    span: Span


@dataclass(frozen=True)
class Use:
    what: str
    target: Ref
    span: Span


@dataclass(frozen=True)
class MountStmt:
    capsule: Ref
    target: Ref
    span: Span


@dataclass(frozen=True)
class FixStmt:
    capsule: Ref
    span: Span


@dataclass(frozen=True)
class LinkStmt:
    a: Ref
    b: Ref
    element: Ref
    span: Span


@dataclass(frozen=True)
class ObserveDecl:
    name: str
    call: Call
    span: Span


@dataclass(frozen=True)
class RequireDecl:
    call: Call
    op: str              # ">=", "<=", ">", "<", "in"
    value: Expr
    upper: Expr | None
    text: str
    span: Span


# ---- programs ---------------------------------------------------------------------------------

@dataclass(frozen=True)
class ToneExpr:
    frequency: Expr
    amplitude: Expr
    phase: Expr | None
    span: Span


@dataclass(frozen=True)
class Options:
    limit: Expr | None = None
    slew: Expr | None = None
    margin: Expr | None = None
    using: Expr | None = None


@dataclass(frozen=True)
class DriveS:
    tones: tuple[ToneExpr, ...]
    duration: Expr
    options: Options
    span: Span


@dataclass(frozen=True)
class SweepS:
    f_start: Expr
    f_stop: Expr
    amplitude: Expr
    duration: Expr
    log: bool
    options: Options
    span: Span


@dataclass(frozen=True)
class PauseS:
    duration: Expr
    span: Span


@dataclass(frozen=True)
class FollowS:
    capsule: Ref
    path: Call
    duration: Expr | None
    speed: Expr | None
    options: Options
    span: Span


@dataclass(frozen=True)
class SwitchS:
    latch: Ref
    state: str
    state_span: Span
    options: Options
    span: Span


@dataclass(frozen=True)
class HoldS:
    gap: Call
    mode: str            # "above" | "cross"
    bound: Expr | None
    duration: Expr
    options: Options
    span: Span


@dataclass(frozen=True)
class ProgramDecl:
    name: str
    steps: tuple
    span: Span


@dataclass(frozen=True)
class Module:
    """One parsed file."""

    file: str
    statements: tuple
    source: str = field(repr=False, default="")


# ---- moving statements ------------------------------------------------------------------------

def shift_lines(node, delta: int):
    """``node`` (a statement, an expression, or a tuple of them) with every span ``delta`` lines
    further down: the tree a parse of the same text ``delta`` lines lower gives (columns are the
    same). The editor's incremental parse uses it when an inserted or deleted line moves the
    statements after it. A span without an end (lark's empty position, always line 1 in a parse)
    is kept as it is. Raises TypeError on a value that is not a syntax tree's."""
    if delta == 0:
        return node
    return _shift(node, delta)


_ATOMS = frozenset({str, float, int, bool, type(None)})
_ATOM_NAMES = frozenset({"str", "float", "int", "bool", "str | None", "bool | None", "float | None"})
#: node class -> (its span fields, its other fields that may hold nodes or spans)
_FIELDS: dict[type, tuple[tuple[str, ...], tuple[str, ...]]] = {}
_new = object.__new__
_set = object.__setattr__


def _fields(t: type):
    """(span fields, node fields) of a node class of this module, from its annotations (a field
    annotated with an atom type holds no span); None for any other type."""
    import dataclasses

    got = _FIELDS.get(t)
    if got is None and dataclasses.is_dataclass(t) and t.__module__ == __name__ and t is not Module:
        fs = dataclasses.fields(t)
        got = _FIELDS[t] = (tuple(f.name for f in fs if f.type == "Span"),
                            tuple(f.name for f in fs if f.type != "Span" and f.type not in _ATOM_NAMES))
    return got


def _shift(x, d: int):
    t = type(x)
    if t is tuple:
        return tuple([v if type(v) in _ATOMS else _shift(v, d) for v in x])
    if t is Span:
        return _moved(x, d)
    got = _FIELDS.get(t) or _fields(t)
    if got is None:
        if t in _ATOMS:
            return x
        raise TypeError(f"not a syntax tree value: {t.__name__}")
    spans, nodes = got
    old = x.__dict__
    new = old.copy()
    for k in spans:
        new[k] = _moved(old[k], d)
    for k in nodes:
        v = old[k]
        if v is not None:
            new[k] = _shift(v, d)
    n = _new(t)
    _set(n, "__dict__", new)
    return n


def _moved_fast(s: Span, d: int) -> Span:
    """Span ``s`` ``d`` lines down, built as pydantic's model_construct builds one (without its
    keyword handling: 1 us instead of 4.7; half a 5,000-line file has ~12,000 spans)."""
    if s.end_line is None:
        return s
    n = _new(Span)
    fields = s.__dict__.copy()
    fields["line"] += d
    fields["end_line"] += d
    _set(n, "__dict__", fields)
    _set(n, "__pydantic_fields_set__", s.__pydantic_fields_set__)
    _set(n, "__pydantic_extra__", None)
    _set(n, "__pydantic_private__", None)
    return n


def _moved_constructed(s: Span, d: int) -> Span:
    if s.end_line is None:
        return s
    return Span.model_construct(file=s.file, line=s.line + d, column=s.column, end_line=s.end_line + d,
                                end_column=s.end_column)


def _moved_checked(s: Span, d: int) -> Span:
    """The first move: the fast construction is kept only if it gives pydantic's own span (the
    same fields, equality, hash, dump and repr), so another pydantic version cannot change spans."""
    global _moved
    probe = Span(file="probe", line=2, column=3, end_line=4, end_column=5)
    want = Span(file="probe", line=9, column=3, end_line=11, end_column=5)
    try:
        got = _moved_fast(probe, 7)
        same = got == want and hash(got) == hash(want) and got.model_dump() == want.model_dump() \
            and repr(got) == repr(want) and got.model_fields_set == want.model_fields_set
    except (AttributeError, TypeError, ValueError):  # pragma: no cover - another pydantic
        same = False
    _moved = _moved_fast if same else _moved_constructed
    return _moved(s, d)


_moved = _moved_checked
