"""Evaluation: expressions to values (with units), parameters (with overrides), blocks with `like`.

The :class:`Resolver` checks the dimension of every expression and records each error once, at the
operation that failed, then raises :class:`~acl.design.core.Fail`; it builds no models (the
builders do).
"""
from __future__ import annotations

import dataclasses
import math
import sys

from acl.design.core import D, IDENTS, SCHEMAS, Fail, example, what_is
from acl.design.modules import Loader, ModuleEnv, stdlib_modules
from acl.design.values import CallVal, DeclVal, DirVal, IdentVal, ListVal, RangeVal, StrVal, VecVal, unit_vector
from acl.diagnostics import Diagnostic, DiagnosticBag, DiagnosticError, Span, suggest
from acl.syntax import ast as A
from acl.units import DIMENSIONLESS, DimensionError, Quantity, UnitError, describe, parse_unit


class Resolver:
    def __init__(self, env: ModuleEnv, loader: Loader, bag: DiagnosticBag, overrides: dict[str, str]):
        self.main = env
        self.loader = loader
        self.bag = bag
        self.param_values: dict[tuple[int, str], Quantity] = {}
        self.evaluating: dict[tuple[int, str], None] = {}   # ordered: the chain being evaluated
        self.failed_params: set[tuple[int, str]] = set()
        self._entries_cache: dict[tuple[int, int], list] = {}
        self._like_cycle: set[int] = set()   # blocks found on a `like` cycle
        self._like_failed: set[int] = set()  # blocks whose `like` base could not be used (reported)
        self.override_exprs: dict[str, A.Expr | float] = {}   # a float: an SI value (Python API)
        self.override_spans: dict[str, Span] = {}
        self.used_decls: dict[str, tuple[str, A.Block, ModuleEnv]] = {}
        self._parse_overrides(overrides)

    # ---------------------------------------------------------------------------- overrides
    def _parse_overrides(self, overrides: dict[str, str]) -> None:
        from acl.syntax.parser import parse_module

        for name, text in overrides.items():
            span = Span(file="<--set>", line=1, column=1)
            if not isinstance(name, str):
                self.bag.error("E211", f"--set {name!r}: a parameter name is a string", span)
                continue
            if name not in self.main.params:
                self.bag.error("E211", f"--set {name}: the design has no parameter `{name}`", span,
                               suggest(name, self.main.params) or (
                                   "parameters: " + ", ".join(self.main.params) if self.main.params else "the design declares no parameters"))
                continue
            if isinstance(text, (int, float)) and not isinstance(text, bool):
                # a Python number is an SI value: it takes the parameter's own dimension
                if isinstance(text, int) and abs(text) > 1e308:
                    text = math.inf if text > 0 else -math.inf   # float() of a huge int raises: E305 as inf
                if not math.isfinite(text):
                    self.bag.error("E305", f"--set {name}: value {text!r} is not finite", span)
                    continue
                self.override_exprs[name] = float(text)
                self.override_spans[name] = span
                continue
            try:
                mod = parse_module(f"param __override = {text}\n", f"<--set {name}>")
                self.override_exprs[name] = mod.statements[0].value
                self.override_spans[name] = span
            except DiagnosticError as exc:
                for d in exc.diagnostics:
                    self.bag.add(Diagnostic("E212", d.severity, f"--set {name}={text}: {d.message}", span, d.hint))

    # ---------------------------------------------------------------------------- evaluation
    def eval(self, e: A.Expr, env: ModuleEnv):
        """Evaluate an expression; errors are recorded (at the operation that failed) and raise Fail."""
        return self._eval(e, env)

    def _eval(self, e: A.Expr, env: ModuleEnv):
        if isinstance(e, A.Num):
            if not math.isfinite(e.value):
                self.bag.error("E305", "number is not finite (too large for a 64-bit float)", e.span)
                raise Fail()
            if e.underflow:
                self.bag.error("E305", "number is too small for a 64-bit float (below 2.2e-308: it would read as 0)",
                               e.span, "write 0 if zero is meant")
                raise Fail()
            return Quantity(e.value)
        if isinstance(e, A.Qty):
            try:
                factor, dims = parse_unit(e.unit)
            except UnitError as exc:
                self.bag.error("E302", str(exc), e.span, exc.hint)
                raise Fail()
            v = e.value * factor
            if not math.isfinite(v):
                self.bag.error("E305", "quantity is not finite", e.span)
                raise Fail()
            if e.underflow or (e.value != 0 and abs(v) < sys.float_info.min):
                self.bag.error("E305", "quantity is too small for a 64-bit float in SI units (below 2.2e-308: it would "
                               "read as 0)", e.span, "write 0 if zero is meant")
                raise Fail()
            return Quantity(v, dims)
        if isinstance(e, A.Str):
            return StrVal(e.value)
        if isinstance(e, A.Dir):
            v = [0.0, 0.0, 0.0]
            v["xyz".index(e.axis)] = float(e.sign)
            return DirVal(tuple(v))
        if isinstance(e, A.Ref):
            return self.lookup(e, env)
        if isinstance(e, A.Vec):
            items = tuple(self._eval(i, env) for i in e.items)
            if not all(isinstance(i, Quantity) for i in items):
                self.bag.error("E304", "vector components must be quantities", e.span)
                raise Fail()
            return VecVal(items)
        if isinstance(e, A.Range):
            lo, hi = self._eval(e.lower, env), self._eval(e.upper, env)
            lo, hi = self._num(lo, e.lower), self._num(hi, e.upper)
            if lo.dims != hi.dims:
                self.bag.error("E303", str(DimensionError(lo.dims, hi.dims, "..")), e.span)
                raise Fail()
            return RangeVal(lo, hi)
        if isinstance(e, A.ListExpr):
            return ListVal(tuple(self._eval(i, env) for i in e.items))
        if isinstance(e, A.Call):
            args = tuple(self._eval(a, env) for a in e.args)
            kwargs = tuple((k, self._eval(v, env)) for k, v in e.kwargs)
            return CallVal(e.name, args, kwargs, e.span)
        if isinstance(e, A.Neg):
            v = self._eval(e.operand, env)
            if isinstance(v, DirVal):
                return DirVal(tuple(-c for c in v.vector))
            return -self._num(v, e.operand)
        if isinstance(e, A.BinOp):
            # a chain `a + b + ... ` is left-nested: walk its left operands iteratively (a flat sum of 1,000
            # terms is 1,000 BinOps deep), evaluating in the order the recursion did: left, right, operator
            spine = []
            while isinstance(e, A.BinOp):
                spine.append(e)
                e = e.left
            acc = self._eval(e, env)
            for node in reversed(spine):
                acc = self._apply(node, acc, self._eval(node.right, env))
            return acc
        self.bag.error("E304", "unsupported expression", e.span)
        raise Fail()

    def _apply(self, e: A.BinOp, left, right):
        """``left e.op right``, or a located E303/E305 and Fail."""
        try:
            out = self._binop(e, left, right)
            if not _finite(out):
                self.bag.error("E305", f"result of `{e.op}` is not finite (overflow)", e.span,
                               "check the magnitudes and units of both sides")
                raise Fail()
            return out
        except DimensionError as exc:
            self.bag.error("E303", str(exc), e.span)
        except ZeroDivisionError:
            self.bag.error("E305", "division by zero", e.span)
        except OverflowError:
            self.bag.error("E305", f"result of `{e.op}` is not finite (overflow)", e.span,
                           "check the magnitudes and units of both sides")
        except ValueError as exc:
            self.bag.error("E305", str(exc), e.span)
        raise Fail()

    def _binop(self, e: A.BinOp, left, right):
        """Arithmetic on quantities, vectors and directions; raises the unit layer's errors."""
        if isinstance(left, VecVal) and isinstance(right, VecVal) and e.op in "+-" and len(left.items) == len(right.items):
            op = (lambda a, b: a + b) if e.op == "+" else (lambda a, b: a - b)
            return VecVal(tuple(op(a, b) for a, b in zip(left.items, right.items)))
        if isinstance(left, VecVal) and isinstance(right, Quantity) and e.op in "*/":
            return VecVal(tuple(a * right if e.op == "*" else a / right for a in left.items))
        if isinstance(left, Quantity) and isinstance(right, VecVal) and e.op == "*":
            return VecVal(tuple(left * b for b in right.items))
        if isinstance(left, DirVal) and isinstance(right, Quantity) and e.op == "*":
            return VecVal(tuple(Quantity(c) * right for c in left.vector))
        if isinstance(left, Quantity) and isinstance(right, DirVal) and e.op == "*":
            return VecVal(tuple(left * Quantity(c) for c in right.vector))
        a, b = self._num(left, e.left), self._num(right, e.right)
        return {"+": a.__add__, "-": a.__sub__, "*": a.__mul__, "/": a.__truediv__, "^": a.__pow__}[e.op](b)

    def _num(self, v, e: A.Expr) -> Quantity:
        if isinstance(v, Quantity):
            return v
        self.bag.error("E304", f"expected a number or quantity, found {what_is(v)}", e.span)
        raise Fail()

    def lookup(self, ref: A.Ref, env: ModuleEnv):
        parts = list(ref.parts)
        head = parts[0]
        cur_env = env
        if head in env.imports and len(parts) >= 2:
            target = env.imports[head]
            if isinstance(target, tuple):
                self.bag.error("E212", f"`{head}` is a declaration, not a module", ref.span)
                raise Fail()
            cur_env = target
            parts = parts[1:]
            head = parts[0]
        elif head in env.imports and len(parts) == 1:
            target = env.imports[head]
            if isinstance(target, tuple):
                tenv, name = target
                return self._named(tenv, name, ref)
            self.bag.error("E304", f"`{head}` is a module; name one of its declarations (`{head}.NAME`)", ref.span,
                           _members_hint(target))
            raise Fail()
        if len(parts) > 1:
            if head in cur_env.decls:  # member access such as arm.tip: handled by callers
                self.bag.error("E304", f"`{ref.dotted}` is a point, not a value", ref.span)
                raise Fail()
            self.bag.error("E201", f"unknown name `{ref.dotted}`", ref.span,
                           _import_hint(head, cur_env) or
                           suggest(head, list(cur_env.imports) + list(cur_env.decls) + list(cur_env.params)))
            raise Fail()
        return self._named(cur_env, head, ref)

    def _named(self, env: ModuleEnv, name: str, ref: A.Ref):
        if name in env.params:
            return self.param(env, name)
        if name in env.decls:
            blk = env.decls[name]
            return DeclVal(blk.kind, ref.dotted, blk, env)
        return IdentVal(name) if len(ref.parts) == 1 and env is self.main and name in IDENTS else self._unknown(env, name, ref)

    def _unknown(self, env, name, ref):
        hint = None
        if name in ("x", "y", "z"):
            hint = f"a direction carries its sign: did you mean `+{name}` (or `-{name}`)?"
        self.bag.error("E201", f"unknown name `{ref.dotted}`", ref.span,
                       hint or suggest(name, list(env.params) + list(env.decls) + list(env.imports)))
        raise Fail()

    def param(self, env: ModuleEnv, name: str) -> Quantity:
        key = (id(env), name)
        if key in self.param_values:
            return self.param_values[key]
        if key in self.failed_params:      # already reported once
            raise Fail()
        decl = env.params[name]
        if not self.evaluating:  # outermost: evaluate what it depends on first, so nothing recurses deeply
            self._evaluate_dependencies(env, name)
            if key in self.failed_params:
                raise Fail()
        if key in self.evaluating:
            chain = [n for (e, n) in self.evaluating if e == id(env)]
            chain = chain[chain.index(name):] + [name] if name in chain else [name, name]
            self.bag.error("E214", f"parameter `{name}` depends on itself: {' -> '.join(chain)}", decl.span,
                           "give one of them a value that does not refer back")
            raise Fail()
        self.evaluating[key] = None
        ok = False
        try:
            value = self._eval(decl.value, env)
            if not isinstance(value, Quantity):
                self.bag.error("E304", f"parameter `{name}` must be a number or quantity, not {what_is(value)}", decl.value.span)
                raise Fail()
            if env is self.main and name in self.override_exprs:
                ov = self.override_exprs[name]
                ov = Quantity(ov, value.dims) if isinstance(ov, float) else self.eval(ov, env)
                if not isinstance(ov, Quantity) or ov.dims != value.dims:
                    self.bag.error("E301", f"--set {name}: expected {describe(value.dims)}, got "
                                   f"{describe(ov.dims) if isinstance(ov, Quantity) else what_is(ov)}",
                                   self.override_spans[name], f"write it with a unit, e.g. --set {name}={example(value.dims)}")
                    raise Fail()
                value = ov
            ok = True
        finally:
            self.evaluating.pop(key, None)
            if not ok:
                self.failed_params.add(key)
        self.param_values[key] = value
        return value

    def _param_deps(self, env: ModuleEnv, name: str):
        """The parameters a parameter's expression (and its --set override) names, as (env, name)."""
        exprs = [env.params[name].value]
        if env is self.main and isinstance(self.override_exprs.get(name), A.Expr):
            exprs.append(self.override_exprs[name])
        out = []
        for ref in _refs(exprs):
            parts, head = ref.parts, ref.parts[0]
            target = env.imports.get(head)
            if target is not None:
                if isinstance(target, tuple):
                    if len(parts) == 1 and target[1] in target[0].params:
                        out.append((target[0], target[1]))
                elif len(parts) == 2 and parts[1] in target.params:
                    out.append((target, parts[1]))
            elif len(parts) == 1 and head in env.params:
                out.append((env, head))
        return out

    def _evaluate_dependencies(self, env: ModuleEnv, name: str) -> None:
        """Evaluate the parameters that `name` depends on, deepest first (an iterative walk).

        A chain of any length then costs one level of recursion per parameter evaluated; a cycle is
        reported here once, naming the whole cycle, and every parameter on it fails quietly after.
        """
        state = {(id(env), name): 1}            # 1: on the walk's stack, 2: done
        stack = [(env, name, iter(self._param_deps(env, name)))]
        order = []
        while stack:
            e, n, deps = stack[-1]
            for e2, n2 in deps:
                k2 = (id(e2), n2)
                if k2 in self.param_values or k2 in self.failed_params or state.get(k2) == 2:
                    continue
                if state.get(k2) == 1:   # a cycle: from n2 around to here
                    names = [x[1] for x in stack]
                    names = names[names.index(n2):] + [n2] if n2 in names else [n2, n2]
                    decl = e2.params[n2]
                    shown = names if len(names) <= 12 else names[:5] + ["..."] + names[-5:]
                    self.bag.error("E214", f"parameter `{n2}` depends on itself: {' -> '.join(shown)}"
                                   + (f" ({len(names) - 1} parameters)" if len(names) > 12 else ""), decl.span,
                                   "give one of them a value that does not refer back")
                    start = next(i for i, x in enumerate(stack) if (id(x[0]), x[1]) == k2)
                    for x in stack[start:]:
                        self.failed_params.add((id(x[0]), x[1]))
                    continue
                state[k2] = 1
                stack.append((e2, n2, iter(self._param_deps(e2, n2))))
                break
            else:
                stack.pop()
                state[(id(e), n)] = 2
                order.append((e, n))
        for e, n in order[:-1]:
            try:
                self.param(e, n)
            except Fail:
                pass

    # ---------------------------------------------------------------------------- typed getters
    def q(self, e: A.Expr, env: ModuleEnv, unit: str, what: str) -> float:
        v = self.eval(e, env)
        want = D(unit)
        if not isinstance(v, Quantity):
            self.bag.error("E304", f"{what}: expected {describe(want)}, found {what_is(v)}", e.span)
            raise Fail()
        if v.dims != want:
            hint = None
            if v.dimensionless and want != DIMENSIONLESS:
                hint = f"add a unit, e.g. `{example(want)}`"
            self.bag.error("E301", f"{what}: expected {describe(want)}, found {describe(v.dims)}", e.span, hint)
            raise Fail()
        return v.value

    def vec(self, e: A.Expr, env: ModuleEnv, unit: str, what: str) -> tuple[float, float, float]:
        v = self.eval(e, env)
        if not isinstance(v, VecVal) or len(v.items) != 3:
            self.bag.error("E304", f"{what}: expected a 3-D point `(x, y, z)`, found {what_is(v)}", e.span)
            raise Fail()
        want = D(unit)
        for item, sub in zip(v.items, e.items if isinstance(e, A.Vec) else [e] * 3):
            if item.dims != want and not (item.value == 0 and item.dimensionless):
                self.bag.error("E301", f"{what}: coordinates must be {describe(want)}, found {describe(item.dims)}",
                               sub.span, "a bare 0 is allowed; other coordinates need a unit")
                raise Fail()
        return tuple(i.value for i in v.items)  # type: ignore[return-value]

    def direction(self, e: A.Expr, env: ModuleEnv, what: str) -> tuple[float, float, float]:
        v = self.eval(e, env)
        if isinstance(v, DirVal):
            return v.vector
        if isinstance(v, VecVal) and len(v.items) == 3 and all(i.dimensionless for i in v.items):
            u = unit_vector(tuple(i.value for i in v.items))
            if u is None:
                self.bag.error("E409", f"{what}: direction has zero length", e.span)
                raise Fail()
            return u
        self.bag.error("E304", f"{what}: expected a direction (`+x`, `-z`, or `(1, 1, 0)`), found {what_is(v)}", e.span)
        raise Fail()

    # ---------------------------------------------------------------------------- blocks
    def entries(self, blk: A.Block, env: ModuleEnv) -> list[tuple[object, ModuleEnv]]:
        """Entries of a block with `like` inheritance resolved: (entry, env) pairs, child last wins.

        The `like` chain is followed iteratively (any length); each block's merged entries are
        computed once, so an error in a shared base is reported once.
        """
        cache = self._entries_cache
        ck = (id(blk), id(env))
        if ck in cache:
            return cache[ck]
        chain = [(blk, env)]
        on_chain = {id(blk)}
        base: list[tuple[object, ModuleEnv]] = []
        cyclic = False   # blocks on a cycle are merged again from their own start (each reports it)
        cur, cenv = blk, env
        while cur.like is not None:
            try:
                target = self.eval(cur.like, cenv)
            except Fail:
                self._like_failed.update(id(x[0]) for x in chain)
                break
            if not isinstance(target, DeclVal):
                self.bag.error("E207", f"`like` needs a {cur.kind}, found {what_is(target)}", cur.like.span)
                self._like_failed.update(id(x[0]) for x in chain)
                break
            if target.kind != cur.kind:
                self.bag.error("E207", f"`{cur.name}` is a {cur.kind} but `{cur.like.dotted}` is a {target.kind}", cur.like.span)
                self._like_failed.update(id(x[0]) for x in chain)
                break
            if id(target.node) in on_chain:
                self.bag.error("E214", f"`like` cycle through `{cur.like.dotted}`", cur.like.span)
                cyclic = True
                ids = [id(x[0]) for x in chain]
                self._like_cycle.update(ids[ids.index(id(target.node)):])
                break
            tk = (id(target.node), id(target.env))
            if tk in cache and id(target.node) not in self._like_cycle:
                base = cache[tk]
                if id(target.node) in self._like_failed:
                    self._like_failed.update(id(x[0]) for x in chain)
                break
            chain.append((target.node, target.env))
            on_chain.add(id(target.node))
            cur, cenv = target.node, target.env
        for b, e in reversed(chain):   # the deepest base first
            own_keys: dict[str, Span] = {}
            own = []
            for ent in b.entries:
                k = _entry_key(ent)
                if k in own_keys:
                    self.bag.error("E206", f"`{k}` given twice in `{b.name or b.kind}` (first at line {own_keys[k].line})",
                                   ent.key_span if isinstance(ent, A.Assign) else ent.kind_span)
                    continue
                own_keys[k] = ent.span
                own.append((ent, e))
            base = [(x, en) for x, en in base if _entry_key(x) not in own_keys] + own
            if not cyclic or b is blk:
                cache[(id(b), id(e))] = base
        return base

    def incomplete(self, blk: A.Block) -> bool:
        """Whether the block's `like` base failed (reported there): its missing entries are not news."""
        return id(blk) in self._like_failed

    def assigns(self, blk: A.Block, env: ModuleEnv, schema_name: str, allowed_blocks=()) -> dict[str, tuple[A.Assign, ModuleEnv]]:
        schema = SCHEMAS[schema_name]
        out: dict[str, tuple[A.Assign, ModuleEnv]] = {}
        for ent, en in self.entries(blk, env):
            if isinstance(ent, A.Assign):
                if ent.key not in schema:
                    self.bag.error("E203", f"unknown key `{ent.key}` in {schema_name}", ent.key_span,
                                   suggest(ent.key, schema) or f"{schema_name} keys: " + ", ".join(schema))
                    continue
                out[ent.key] = (ent, en)
            elif ent.kind not in allowed_blocks:
                self.bag.error("E203", f"unexpected block `{ent.kind}` in {schema_name}", ent.kind_span,
                               suggest(ent.kind, list(allowed_blocks) + list(schema)) or (
                                   f"{schema_name} may contain: " + ", ".join(allowed_blocks) if allowed_blocks else f"{schema_name} has no nested blocks"))
        for key, spec in schema.items():
            if spec.required and key not in out and not self.incomplete(blk):
                self.bag.error("E204", f"{schema_name} `{blk.name or ''}` is missing `{key}`".replace(" ``", ""), blk.span,
                               f"add `{key} = {example(D(spec.unit)) if spec.unit is not None else '...'}`")
        return out

    def get(self, keys, key: str, schema_name: str, what: str, unit=None):
        """Evaluate one key with its schema; returns the default when absent; raises Fail on error."""
        spec = SCHEMAS[schema_name][key]
        if key not in keys:
            if spec.required:
                raise Fail()
            return spec.default
        ent, env = keys[key]
        label = f"{what}.{key}"
        kind = spec.kind
        if kind == "q":
            return self.q(ent.value, env, spec.unit, label)
        if kind == "vec":
            return self.vec(ent.value, env, spec.unit, label)
        if kind == "dir":
            return self.direction(ent.value, env, label)
        if kind.startswith("ref:"):
            want = kind[4:]
            v = self.eval(ent.value, env)
            if not isinstance(v, DeclVal) or v.kind != want:
                self.bag.error("E207", f"{label}: expected a {want}, found {what_is(v)}", ent.value.span,
                               self.kind_hint(want, env))
                raise Fail()
            return v
        if kind == "range":
            return self.range_(ent.value, env, spec.unit, label)
        return (self.eval(ent.value, env), ent)

    def kind_hint(self, kind: str, env: ModuleEnv) -> str | None:
        names = [n for n, b in env.decls.items() if b.kind == kind]
        for alias, tgt in env.imports.items():
            if not isinstance(tgt, tuple):
                names += [f"{alias}.{n}" for n, b in tgt.decls.items() if b.kind == kind]
        return ("available: " + ", ".join(names[:8])) if names else f"declare a {kind} or import one from the stdlib"

    def range_(self, e: A.Expr, env: ModuleEnv, unit: str, what: str) -> tuple[float, float]:
        # ranges are written as a 2-list `[lo, hi]` or a call range(lo, hi); `lo .. hi` in require/free
        v = self.eval(e, env)
        if isinstance(v, RangeVal):
            v = ListVal((v.lower, v.upper))
        items = v.items if isinstance(v, (ListVal, VecVal)) else (v.args if isinstance(v, CallVal) else None)
        want = D(unit)
        if not items or len(items) != 2 or not all(isinstance(i, Quantity) and i.dims == want for i in items):
            self.bag.error("E304", f"{what}: expected a range `lo .. hi` of {describe(want)}", e.span)
            raise Fail()
        lo, hi = items[0].value, items[1].value
        if not lo < hi:
            self.bag.error("E306", f"{what}: range is empty (lower {lo:g} >= upper {hi:g})", e.span)
            raise Fail()
        return lo, hi

def _finite(v) -> bool:
    if isinstance(v, Quantity):
        return math.isfinite(v.value)
    if isinstance(v, VecVal):
        return all(math.isfinite(i.value) for i in v.items)
    return True


def _refs(exprs):
    """Every name reference inside the expressions (an iterative walk over any expression node)."""
    stack = list(exprs)
    while stack:
        x = stack.pop()
        if isinstance(x, A.Ref):
            yield x
        elif isinstance(x, A.Expr):
            stack.extend(v for v in (getattr(x, f.name) for f in dataclasses.fields(x)) if isinstance(v, (A.Expr, tuple)))
        elif isinstance(x, tuple):
            stack.extend(v for v in x if isinstance(v, (A.Expr, tuple)))


def _entry_key(ent) -> str:
    if isinstance(ent, A.Assign):
        return ent.key
    return f"{ent.kind} {ent.name}" if ent.name else ent.kind


def _import_hint(head: str, env: ModuleEnv) -> str | None:
    """`media.pbs` without `import stdlib.media`: say which import is missing."""
    if head in env.imports or head in env.decls or head in env.params:
        return None
    if head in stdlib_modules():
        return f"`{head}` is a stdlib module: add `import stdlib.{head}`"
    return None


def _members_hint(env: ModuleEnv) -> str | None:
    names = list(env.decls) + list(env.params)
    return ("it declares: " + ", ".join(names[:10])) if names else None
