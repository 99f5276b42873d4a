"""Parameters -> the design's float fields, for many points at once: resolve once, perturb the SI arrays.

Parameters reach fields through expressions (``radius = r``, ``center = (0, 0, gap / 2)``).  The map
from parameters to fields is found by resolving the design a few times with overrides
(:func:`field_map`): one step per parameter gives the coefficients, then joint points across the
sweep's range check that the map is affine to round-off.  Affine fields are then computed for every
point as ``base + (x - x0) @ coef`` (exact: an affine expression has no other form); a field that
depends on a parameter in any other way (``radius = r^2 / 10 um``) is resolved exactly once per
unique value of the parameters it depends on, with a warning, never linearised.  Derived fields stay
consistent: a cylinder's or prism's ``cavity.volume`` is recomputed from its sizes.

Each point is then checked as the resolver checks a design (positive sizes E401, orifice fits its
face E402, printable features E407, slenderness E408, latch angle E411, substrate E404, overlap E403):
an invalid point is marked with its diagnostic code, never raised.

Field path: the Design model's attribute names joined by '.', an element of a tuple of named models
by its name, any other tuple element (Vec3 component, require, step) by its index, a parameter's
value as ``params.NAME``: ``capsules.act.orifices.jet.radius``, ``beams.arm.tip.2``.
"""
from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field

import numpy as np
from pydantic import BaseModel

from acl.design.model import Design
from acl.diagnostics import DiagnosticError

RTOL = 1e-9           # an affine map reproduces every field to this relative error (round-off is ~1e-15)
N_CHECKS = 4          # random joint points checked besides the box's two corners


class SweepWarning(UserWarning):
    """A sweep works but slower or with a caveat (a field nonlinear in a parameter)."""


# ------------------------------------------------------------------------------------------------
# Field paths
# ------------------------------------------------------------------------------------------------

def flatten(design: Design) -> dict[str, float]:
    """Every float field of the design by its path (module docstring)."""
    out = {f"params.{p.name}": float(p.value) for p in design.params}
    for name in type(design).model_fields:
        if name not in ("params", "file", "sources"):
            _walk(getattr(design, name), name, out)
    return out


def _walk(obj, prefix: str, out: dict) -> None:
    if isinstance(obj, BaseModel):
        for name in type(obj).model_fields:
            if name != "span":
                _walk(getattr(obj, name), f"{prefix}.{name}", out)
    elif isinstance(obj, float):
        out[prefix] = obj
    elif isinstance(obj, tuple):
        for i, item in enumerate(obj):
            key = item.name if isinstance(getattr(item, "name", None), str) and isinstance(item, BaseModel) else str(i)
            _walk(item, f"{prefix}.{key}", out)
    elif isinstance(obj, dict):
        for k, v in obj.items():
            _walk(v, f"{prefix}.{k}", out)


def field_value(design: Design, path: str) -> float:
    """The nominal value of one field path."""
    parts = path.split(".")
    if parts[0] == "params":
        return float(design.param(parts[1]).value)
    obj = design
    for p in parts:
        obj = _child(obj, p)
    return float(obj)


def _child(obj, key: str):
    if isinstance(obj, BaseModel):
        return getattr(obj, key)
    if isinstance(obj, dict):
        return obj[key]
    if isinstance(obj, tuple):
        if key.isdigit():
            return obj[int(key)]
        for item in obj:
            if getattr(item, "name", None) == key:
                return item
    raise KeyError(key)


def _replace(obj, parts: list[str], value: float):
    """``obj`` with the field at ``parts`` set to ``value`` (a new object; the input is untouched)."""
    if not parts:
        return float(value)
    key, rest = parts[0], parts[1:]
    if isinstance(obj, BaseModel):
        data = {n: getattr(obj, n) for n in type(obj).model_fields}
        if isinstance(obj, Design) and key == "params":
            data["params"] = tuple(p.model_copy(update={"value": float(value)}) if p.name == rest[0] else p for p in obj.params)
        else:
            data[key] = _replace(data[key], rest, value)
        return type(obj).model_construct(**data)    # fields only: no stale cached lookups
    if isinstance(obj, dict):
        return {**obj, key: _replace(obj[key], rest, value)}
    items = list(obj)
    i = int(key) if key.isdigit() else next(j for j, it in enumerate(items) if getattr(it, "name", None) == key)
    items[i] = _replace(items[i], rest, value)
    return tuple(items)


# ------------------------------------------------------------------------------------------------
# The batch handed to evaluation (contract with acl.sweep.evaluate)
# ------------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class FieldBatch:
    design: Design                  # the nominal resolved design (resolved ONCE)
    n: int                          # number of points
    fields: dict[str, np.ndarray]   # field path -> SI float array (n,), only the fields that vary
    valid: np.ndarray               # bool (n,): the point passes the geometry/printability checks
    code: np.ndarray                # str (n,): diagnostic code of an invalid point, "" when valid

    def get(self, path: str) -> np.ndarray:
        """The varying array of ``path``, or its nominal value broadcast to (n,)."""
        arr = self.fields.get(path)
        if arr is not None:
            return arr
        return np.full(self.n, field_value(self.design, path))


def materialize(batch: FieldBatch, i: int) -> Design:
    """Point ``i`` as a plain Design (tests and per-point fallbacks)."""
    d = batch.design
    for path, arr in batch.fields.items():
        d = _replace(d, path.split("."), float(arr[i]))
    return d


# ------------------------------------------------------------------------------------------------
# The map parameters -> fields
# ------------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class FieldMap:
    """How fields follow parameters: ``base + (x - nominal) @ coef`` for ``linear`` paths, exact
    re-resolution for ``exact`` paths (depending on the parameters ``exact_params``)."""

    source: str
    overrides: dict
    search_paths: tuple
    names: tuple[str, ...]
    nominal: np.ndarray
    linear: dict[str, np.ndarray]
    exact: tuple[str, ...] = ()
    exact_params: tuple[str, ...] = ()
    derived: tuple[str, ...] = ()
    notes: tuple[str, ...] = field(default=())
    proportional: dict[str, tuple[int, float]] = field(default_factory=dict)   # path -> (parameter index, ratio)

    def predict(self, path: str, base: float, x: np.ndarray) -> np.ndarray:
        """Field ``path`` at points x (n, k) (or (k,)): proportional paths as ``ratio * x_i`` (exact copies
        of a parameter, zeros stay zero), the others ``base + (x - nominal) @ coef``."""
        prop = self.proportional.get(path)
        if prop is not None:
            i, ratio = prop
            col = x[..., i]
            return col.copy() if ratio == 1.0 else col * ratio
        c = self.linear[path]
        nz = np.flatnonzero(c)
        return base + (x[..., nz] - self.nominal[nz]) @ c[nz]


def _load(source: str, overrides: dict, search_paths) -> Design:
    from acl.design.resolve import load_design

    return load_design(source, overrides=overrides, search_paths=search_paths)


def _derived_volumes(design: Design) -> list[str]:
    return [f"capsules.{c.name}.cavity.volume" for c in design.capsules if c.cavity.shape in ("cylinder", "prism")]


def cavity_volume(shape: str, radius=None, side=None, height=None):
    """Gas volume of a cylinder (pi r^2 h) or an equilateral prism (sqrt(3)/4 s^2 h), as acl.design.geometry."""
    if shape == "cylinder":
        return math.pi * radius**2 * height
    return math.sqrt(3) / 4 * side**2 * height


def field_map(design: Design, names, box: dict[str, tuple[float, float]] | None = None, overrides=None,
              search_paths=(), seed: int = 0) -> FieldMap:
    """Find and check the map from parameters ``names`` to the design's fields (module docstring).

    ``design`` is the nominal design, loaded from ``design.file`` with ``overrides`` (``--set``);
    ``box`` the range of each parameter (acl.sweep.spec.SweepSpec.box) where affinity is checked.
    """
    names = tuple(names)
    overrides = dict(overrides or {})
    source = design.file
    import os

    if names and not os.path.isfile(source):
        from acl.diagnostics import Span, error

        raise DiagnosticError([error("E-USAGE", f"the design `{source}` is not a file: a sweep resolves it again with "
                                     "other parameter values", Span(file=source, line=1, column=1),
                                     "save the design to a file and pass its path")])
    x0 = np.array([design.param(n).value for n in names], float)
    flat0 = flatten(design)
    keys = set(flat0)
    derived = [p for p in _derived_volumes(design)]
    box = box or {n: (v, v) for n, v in zip(names, x0)}
    coef: dict[str, np.ndarray] = {}
    structural = []

    def resolve(x):
        ov = {**overrides, **{n: float(v) for n, v in zip(names, x)}}
        return flatten(_load(source, ov, search_paths))

    for i, n in enumerate(names):
        lo, hi = box.get(n, (x0[i], x0[i]))
        h = max(hi - x0[i], x0[i] - lo)
        if not h > 0:
            h = abs(x0[i]) * 0.1 or 1e-9
        flat1, step = None, 0.0
        # the largest step that still resolves (round-off shrinks with it); when a huge range (a
        # spread of metres) resolves nowhere within 12 quarterings, start again from 10 % of the value
        for h in (h, 0.1 * abs(x0[i]) or 1e-9):
            for _ in range(12):
                for s in (h, -h):
                    x = x0.copy()
                    x[i] += s
                    try:
                        flat1, step = resolve(x), s
                        break
                    except DiagnosticError:
                        continue
                if flat1 is not None:
                    break
                h /= 4
            if flat1 is not None:
                break
        if flat1 is None or set(flat1) != keys:
            structural.append(n)
            continue
        for path, v1 in flat1.items():
            if v1 != flat0[path]:
                coef.setdefault(path, np.zeros(len(names)))[i] = (v1 - flat0[path]) / step
    derived = [p for p in derived if p in coef or _sizes_vary(p, coef)]
    for p in derived:
        coef.pop(p, None)
    proportional = {}
    for p, c in coef.items():        # a field that is a parameter times a constant: keep it exact (radius = r)
        nz = np.flatnonzero(c)
        if len(nz) == 1 and x0[nz[0]] != 0 and abs(flat0[p] - c[nz[0]] * x0[nz[0]]) <= 1e-12 * abs(flat0[p]):
            proportional[p] = (int(nz[0]), 1.0 if flat0[p] == x0[nz[0]] else flat0[p] / x0[nz[0]])
    tmp = FieldMap(source=source, overrides=overrides, search_paths=(), names=names, nominal=x0, linear=coef,
                   proportional=proportional)
    # check at the box's corners and random joint points
    rng = np.random.default_rng(seed)
    lo = np.array([box.get(n, (v, v))[0] for n, v in zip(names, x0)])
    hi = np.array([box.get(n, (v, v))[1] for n, v in zip(names, x0)])
    points = [lo, hi] + [lo + (hi - lo) * rng.random(len(names)) for _ in range(N_CHECKS)]
    bad: dict[str, set] = {}
    verified = 0
    for x in points:
        flat = None
        for _ in range(6):
            try:
                flat = resolve(x)
                break
            except DiagnosticError:
                x = x0 + (x - x0) / 2
        if flat is None or set(flat) != keys:
            continue
        verified += 1
        dx = x - x0
        pred = {p: float(tmp.predict(p, flat0[p], x)) for p in coef}
        for p in derived:
            pred[p] = flat[p]            # recomputed from the sizes, checked below
        for p, v in flat.items():
            want = pred.get(p, flat0[p])
            scale = max(abs(v), abs(flat0[p]), abs(want))
            if abs(v - want) > RTOL * scale + 1e-300:
                bad.setdefault(p, set()).update(n for n, d in zip(names, dx) if d != 0)
        for p in derived:
            cap = p.split(".")[1]
            c = design.capsule(cap).cavity
            base = f"capsules.{cap}.cavity."
            sizes = {k: float(tmp.predict(base + k, flat0[base + k], x)) if base + k in coef else flat0.get(base + k)
                     for k in ("radius", "side", "height")}
            if abs(cavity_volume(c.shape, **sizes) - flat[p]) > RTOL * abs(flat[p]):
                bad.setdefault(p, set()).update(names)
    notes = []
    if not verified and len(names) > 0:
        # no check point resolved even halfway to the nominal: the one-step map is unverified, so no
        # field is trusted as affine (each unique value is resolved exactly; points that do not
        # resolve are invalid with the resolver's code)
        for p, c in coef.items():
            if p not in proportional:
                bad.setdefault(p, set()).update(n for n, ci in zip(names, c) if ci != 0)
        for p in derived:
            bad.setdefault(p, set()).update(names)
        if bad:
            notes.append("no point of the sweep's range resolved to check the parameter-to-field map: "
                         "every field that is not a parameter times a constant is resolved exactly")
    exact = sorted(bad)
    exact_params: set = set()
    for p in exact:
        dep = {n for n, c in zip(names, coef.get(p, np.zeros(len(names)))) if c != 0} | bad[p]
        exact_params |= dep or set(names)
        coef.pop(p, None)
        proportional.pop(p, None)
        if p in derived:
            derived.remove(p)
    if structural:
        from acl.diagnostics import Span, error

        where = design.param(structural[0]).span
        raise DiagnosticError([error("E-USAGE", "cannot sweep " + ", ".join(f"`{n}`" for n in structural)
                                     + ": the design does not resolve near its value, or its structure changes with it",
                                     where if where is not None and where.line else Span(file=source, line=1, column=1),
                                     "a parameter that adds or removes parts, or that no nearby value resolves, "
                                     "cannot be perturbed; vary it with several `acl sweep --set` runs instead")])
    if exact:
        notes.append(f"{len(exact)} field(s) depend nonlinearly on " + ", ".join(f"`{n}`" for n in sorted(exact_params))
                     + f" (e.g. `{exact[0]}`): resolved exactly for each unique value (slower)")
    ordered = tuple(n for n in names if n in exact_params)
    return FieldMap(source=source, overrides=overrides, search_paths=tuple(search_paths), names=names, nominal=x0,
                    linear=coef, exact=tuple(exact), exact_params=ordered, derived=tuple(derived), notes=tuple(notes),
                    proportional=proportional)


def _sizes_vary(volume_path: str, coef) -> bool:
    base = volume_path.rsplit(".", 1)[0]
    return any(f"{base}.{k}" in coef for k in ("radius", "side", "height"))


def field_batch(design: Design, params: dict[str, np.ndarray], fmap: FieldMap | None = None) -> FieldBatch:
    """The fields of the points ``params`` ({parameter name: SI values (n,)}) and their validity.

    ``fmap`` (from :func:`field_map`) is found from the values' own range when omitted; a sweep
    finds it once and gives it to every chunk.
    """
    names = tuple(params)
    if fmap is None:
        box = {n: (float(np.min(v)), float(np.max(v))) for n, v in params.items()} if names else {}
        fmap = field_map(design, names, box)
        for note in fmap.notes:
            warnings.warn(note, SweepWarning, stacklevel=2)
    arrays = [np.asarray(params[n], float) for n in fmap.names]
    n = int(arrays[0].size) if arrays else 0
    x = np.stack(arrays, axis=1) if arrays else np.zeros((0, 0))
    fields: dict[str, np.ndarray] = {}
    for n_, v in zip(fmap.names, arrays):
        fields[f"params.{n_}"] = v
    for path in fmap.linear:
        if not path.startswith("params."):
            fields[path] = fmap.predict(path, field_value(design, path), x)
    valid = np.ones(n, bool)
    code = np.full(n, "", dtype="<U8")
    if fmap.exact:
        _exact_fields(design, fmap, x, fields, valid, code)
    batch = FieldBatch(design=design, n=n, fields=fields, valid=valid, code=code)
    for path in fmap.derived:
        cap = design.capsule(path.split(".")[1])
        base = f"capsules.{cap.name}.cavity."
        sizes = {k: batch.get(base + k) for k in ("radius", "side", "height") if getattr(cap.cavity, k) is not None}
        fields[path] = cavity_volume(cap.cavity.shape, **sizes)
    from acl.sweep.validity import check_points

    check_points(batch)
    _resolver_checks(design, fmap, x, batch)
    return batch


# Program and transducer fields: drive amplitudes, limits, durations, margins and the transducer's
# values are checked vectorised (acl.sweep.validity.check_drives); the others (a tone's frequency,
# a follow path's size) are judged by the resolver.
_RESOLVER_CHECKED = ("programs.", "transducer.")


def _resolver_checks(design, fmap: FieldMap, x: np.ndarray, batch) -> None:
    """Points whose program or transducer fields move get the resolver's verdict: vectorised for the
    fields :func:`acl.sweep.validity.drive_fields_vectorised` names; for any other, each unique value
    of the parameters those fields depend on is loaded once, and an error marks its points invalid
    with the resolver's first error code (as `acl check`), never a valid row for a drive it refuses."""
    from acl.sweep.validity import check_drives, drive_fields_vectorised

    moved = [p for p in batch.fields if p.startswith(_RESOLVER_CHECKED)]
    if not moved or not len(x):
        return
    check_drives(batch)
    moved = [p for p in moved if not drive_fields_vectorised(p)]
    if not moved:
        return
    dep = set()
    for p in moved:
        c = fmap.linear.get(p)
        dep |= {n for n, ci in zip(fmap.names, c) if ci != 0} if c is not None else set(fmap.names)
    cols = [i for i, n in enumerate(fmap.names) if n in dep]
    if not cols:
        return
    uniq, inverse = np.unique(x[:, cols], axis=0, return_inverse=True)
    inverse = inverse.ravel()
    codes = np.full(len(uniq), "", dtype="<U8")
    for u, row in enumerate(uniq):
        ov = {**fmap.overrides, **{fmap.names[i]: float(v) for i, v in zip(cols, row)}}
        try:
            _load(fmap.source, ov, fmap.search_paths)
        except DiagnosticError as exc:
            codes[u] = next((d.code for d in exc.diagnostics if d.is_error), "E000")
    bad = (codes[inverse] != "") & batch.valid
    batch.code[bad] = codes[inverse][bad]
    batch.valid[bad] = False


def _exact_fields(design, fmap: FieldMap, x: np.ndarray, fields: dict, valid: np.ndarray, code: np.ndarray) -> None:
    """Resolve each unique value of the nonlinear parameters exactly; a point that does not resolve
    is invalid with the resolver's first error code (its nonlinear fields are NaN)."""
    cols = [fmap.names.index(n) for n in fmap.exact_params]
    uniq, inverse = np.unique(x[:, cols], axis=0, return_inverse=True)
    inverse = inverse.ravel()
    values = {p: np.full(len(uniq), np.nan) for p in fmap.exact}
    ok = np.ones(len(uniq), bool)
    codes = np.full(len(uniq), "", dtype="<U8")
    for u, row in enumerate(uniq):
        ov = {**fmap.overrides, **{n: float(v) for n, v in zip(fmap.exact_params, row)}}
        try:
            flat = flatten(_load(fmap.source, ov, fmap.search_paths))
        except DiagnosticError as exc:
            ok[u] = False
            codes[u] = next((d.code for d in exc.diagnostics if d.is_error), "E000")
            continue
        for p in fmap.exact:
            values[p][u] = flat.get(p, np.nan)
    for p, v in values.items():
        fields[p] = v[inverse]
    bad = ~ok[inverse]
    valid &= ~bad
    code[bad] = codes[inverse][bad]
