"""The resolver's geometry and printability checks (acl.design.builders, acl.design.checks), per point.

Vectorised over a :class:`~acl.sweep.perturb.FieldBatch` (plus E306, a `free` parameter outside its bounds): each check marks the points it fails with
the diagnostic code the resolver would give the same design, the first failing check winning.
Only fields that can vary are read (directions and shapes are fixed by the nominal design).
"""
from __future__ import annotations

import math

import numpy as np

from acl.design import checks as C


def _mark(batch, bad: np.ndarray, code: str) -> None:
    new = bad & batch.valid
    if new.any():
        batch.code[new] = code
        batch.valid[new] = False


def _vary(batch, prefix: str) -> bool:
    return any(p.startswith(prefix) for p in batch.fields)


def _extent_cols(shape: str, u: np.ndarray, axis, radius, side, height, volume, wall) -> np.ndarray:
    """Support function of a capsule's outer body along unit directions u (n, 3) (acl.design.geometry.half_extent)."""
    if shape in ("cylinder", "prism"):
        ca = np.abs(u @ np.asarray(axis, float))
        across = radius if shape == "cylinder" else side / math.sqrt(3)
        return ca * height / 2 + across * np.sqrt(np.maximum(0.0, 1 - ca * ca)) + wall
    return (3 * volume / (4 * math.pi)) ** (1 / 3) + wall


def check_points(batch) -> None:
    """Fill ``batch.valid``/``batch.code`` in place (the arrays the batch was built with)."""
    d = batch.design
    if not batch.fields:
        return
    g = batch.get
    # E305: a field that is not finite (an expression overflowing at some point)
    for path, arr in batch.fields.items():
        _mark(batch, ~np.isfinite(arr), "E305")
    # E306: a free parameter outside its declared bounds (`free in lo .. hi`)
    for p in d.params:
        arr = batch.fields.get(f"params.{p.name}")
        if arr is not None and p.lower is not None and p.upper is not None:
            _mark(batch, (arr < p.lower) | (arr > p.upper), "E306")
    # E401: sizes that must be positive
    positive = []
    for c in d.capsules:
        base = f"capsules.{c.name}"
        for k in ("radius", "side", "height", "volume", "wall"):
            if getattr(c.cavity, k) is not None:
                positive.append(f"{base}.cavity.{k}")
        positive += [f"{base}.orifices.{o.name}.radius" for o in c.orifices]
    for b in d.beams:
        positive += [f"beams.{b.name}.length", f"beams.{b.name}.youngs_modulus"]
        positive += [f"beams.{b.name}.section.{k}" for k in ("diameter", "width", "thickness") if getattr(b.section, k) is not None]
    for la in d.latches:
        positive += [f"latches.{la.name}.{k}" for k in ("length", "width", "thickness", "youngs_modulus")]
    positive += [f"springs.{s.name}.stiffness" for s in d.springs]
    positive += [f"materials.{m.name}.youngs_modulus" for m in d.materials]
    for path in positive:
        if path in batch.fields:
            _mark(batch, ~(batch.fields[path] > 0), "E401")
    for b in d.beams:
        if batch.fields.get(f"beams.{b.name}.rigid_length") is not None:
            _mark(batch, batch.fields[f"beams.{b.name}.rigid_length"] < 0, "E401")
    # E402: each orifice fits its face (acl.design.builders.Builder._orifice)
    for c in d.capsules:
        base = f"capsules.{c.name}"
        if not _vary(batch, base + "."):
            continue
        cav = c.cavity
        for o in c.orifices:
            R = g(f"{base}.orifices.{o.name}.radius")
            cosine = abs(sum(a * b for a, b in zip(o.normal, cav.axis)))
            end = abs(cosine - 1) < 1e-6
            if cav.shape == "prism":
                side, h = g(f"{base}.cavity.side"), g(f"{base}.cavity.height")
                fits = R < side / (2 * math.sqrt(3)) if end else 2 * R <= np.minimum(side, h)
            elif cav.shape == "cylinder":
                r, h = g(f"{base}.cavity.radius"), g(f"{base}.cavity.height")
                fits = R < r if end else (2 * R <= h) & (R <= r)
            else:
                fits = R < (3 * g(f"{base}.cavity.volume") / (4 * math.pi)) ** (1 / 3)
            _mark(batch, ~fits, "E402")
    # E407: printable features (paper Supplementary Note 1; acl.design.checks._printability)
    lateral, axial = C.PRINT_LATERAL, C.PRINT_AXIAL
    for c in d.capsules:
        base = f"capsules.{c.name}"
        if base + ".cavity.wall" in batch.fields:
            _mark(batch, batch.fields[base + ".cavity.wall"] < lateral, "E407")
        for o in c.orifices:
            p = f"{base}.orifices.{o.name}.radius"
            if p in batch.fields:
                _mark(batch, 2 * batch.fields[p] < lateral, "E407")
    for b in d.beams:
        s, base = b.section, f"beams.{b.name}.section."
        vertical = abs(b.axis[2]) > 0.7
        if s.shape == "circle" and base + "diameter" in batch.fields:
            _mark(batch, batch.fields[base + "diameter"] < (lateral if vertical else axial), "E407")
        if s.shape == "rect":
            if base + "width" in batch.fields:
                _mark(batch, batch.fields[base + "width"] < lateral, "E407")
            if base + "thickness" in batch.fields:
                _mark(batch, batch.fields[base + "thickness"] < (lateral if vertical else axial), "E407")
    for la in d.latches:
        for k, limit in (("width", lateral), ("thickness", axial)):
            p = f"latches.{la.name}.{k}"
            if p in batch.fields:
                _mark(batch, batch.fields[p] < limit, "E407")
    # E408: beam slenderness
    for b in d.beams:
        if not _vary(batch, f"beams.{b.name}."):
            continue
        base = f"beams.{b.name}."
        s = b.section
        feat = g(base + "section.diameter") if s.shape == "circle" else np.minimum(g(base + "section.width"), g(base + "section.thickness"))
        ratio = g(base + "length") / feat
        _mark(batch, ~((ratio >= C.SLENDERNESS[0]) & (ratio <= C.SLENDERNESS[1])), "E408")
    # E411: latch angle in (0, 90) deg
    for la in d.latches:
        p = f"latches.{la.name}.angle"
        if p in batch.fields:
            a = batch.fields[p]
            _mark(batch, ~((a > 0) & (a < math.pi / 2)), "E411")
    # E404: nothing below the substrate
    for c in d.capsules:
        base = f"capsules.{c.name}"
        if not _vary(batch, base + "."):
            continue
        cav = c.cavity
        down = np.tile([0.0, 0.0, -1.0], (batch.n, 1))
        ext = _extent_cols(cav.shape, down, cav.axis, *(_size(batch, base, k, cav) for k in ("radius", "side", "height", "volume", "wall")))
        _mark(batch, g(base + ".center.2") - ext < -1e-12, "E404")
    for b in d.beams:
        if f"beams.{b.name}.clamp.2" in batch.fields or f"beams.{b.name}.tip.2" in batch.fields:
            _mark(batch, np.minimum(g(f"beams.{b.name}.clamp.2"), g(f"beams.{b.name}.tip.2")) < -1e-12, "E404")
    # E403: capsules overlap (acl.design.checks._overlaps, all pairs: designs have few capsules)
    caps = list(d.capsules)
    if len(caps) >= 2 and len(caps) <= 64 and any(_vary(batch, f"capsules.{c.name}.") for c in caps):
        centers = {c.name: np.stack([g(f"capsules.{c.name}.center.{k}") for k in range(3)], axis=1) for c in caps}
        for i, a in enumerate(caps):
            for b in caps[i + 1:]:
                if not (_vary(batch, f"capsules.{a.name}.") or _vary(batch, f"capsules.{b.name}.")):
                    continue
                dvec = centers[b.name] - centers[a.name]
                dist = np.linalg.norm(dvec, axis=1)
                u = dvec / np.where(dist > 0, dist, 1.0)[:, None]
                ea = _extent_cols(a.cavity.shape, u, a.cavity.axis, *(_size(batch, f"capsules.{a.name}", k, a.cavity)
                                                                      for k in ("radius", "side", "height", "volume", "wall")))
                eb = _extent_cols(b.cavity.shape, -u, b.cavity.axis, *(_size(batch, f"capsules.{b.name}", k, b.cavity)
                                                                       for k in ("radius", "side", "height", "volume", "wall")))
                _mark(batch, (dist == 0) | (ea + eb - dist > C.OVERLAP_TOL), "E403")


def _size(batch, base: str, key: str, cav):
    return batch.get(f"{base}.cavity.{key}") if getattr(cav, key) is not None else None
