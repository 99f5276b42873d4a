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
