"""The resolver's geometry and printability checks (acl.design.builders, acl.design.checks), per point.

Vectorised over a :class:`~acl.sweep.perturb.FieldBatch` (plus E306, a `free` parameter outside its bounds; a sweep and
``acl tune`` check that on the chosen values instead, :func:`without_free_ranges`): each check marks the points it fails with
the diagnostic code the resolver would give the same design, the first failing check winning.
Only fields that can vary are read (directions and shapes are fixed by the nominal design).
"""
from __future__ import annotations

import math
import re

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


def without_free_ranges(design):
    """``design`` with its `free` ranges dropped: the batch a sweep or tune evaluates (the one rule of both).

    `free in lo .. hi` bounds the value a designer may choose (a grid's, the nominal, the tuner's
    trial), not the printed device: a device drawn about a value at its bound deviates beyond it by
    its spread, and is a device to evaluate, not an E306 point (issue 28: a tuned design, its values
    on the bounds, swept to yield 0.25 where acl tune had validated 1.0)."""
    params = tuple(q.model_copy(update={"lower": None, "upper": None}) if q.free and q.lower is not None else q
                   for q in design.params)
    return design.model_copy(update={"params": params})


def mark_outside_free_ranges(batch, design, chosen: dict) -> None:
    """E306 at the points whose chosen value (``chosen``: {parameter: SI values before the spreads move
    them}) lies outside its `free` range in ``design``; it wins over any code found before."""
    for p in design.params:
        arr = chosen.get(p.name)
        if arr is None or not p.free or p.lower is None or p.upper is None:
            continue
        bad = (np.asarray(arr) < p.lower) | (np.asarray(arr) > p.upper)
        if bad.any():
            batch.code[bad] = "E306"
            batch.valid[bad] = False


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
    positive += [f"capsules.{c.name}.quality_factor" for c in d.capsules]   # a declared `q` (builders: E401)
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
                # orifices closer than the printable gap: one bubble (acl.design.checks._touching_orifices)
                for oa in a.orifices:
                    for ob in b.orifices:
                        pa = np.stack([g(f"capsules.{a.name}.orifices.{oa.name}.center.{k}") for k in range(3)], axis=1)
                        pb = np.stack([g(f"capsules.{b.name}.orifices.{ob.name}.center.{k}") for k in range(3)], axis=1)
                        _mark(batch, np.linalg.norm(pb - pa, axis=1) < C.PRINT_LATERAL, "E403")


def _size(batch, base: str, key: str, cav):
    return batch.get(f"{base}.cavity.{key}") if getattr(cav, key) is not None else None


# ------------------------------------------------------------------------------------------------
# Programs and transducer (acl.design.builders.Builder.transducer, acl.design.programs._step,
# acl.design.checks.check_programs), per point
# ------------------------------------------------------------------------------------------------

_STEP = re.compile(r"^programs\.(?P<p>[^.]+)\.steps\.(?P<i>\d+)\.(?P<rest>.+)$")
# fields of a step whose checks are vectorised below (anything else, e.g. a tone's frequency, which
# names the batched columns, or a follow path's size, is judged by the resolver per unique value)
_STEP_FIELDS = re.compile(r"^(drive\.tones\.\d+\.(amplitude|phase)|amplitude|duration|limits\.(max_voltage|slew_rate)"
                          r"|margin|bound)$")
_TRANSDUCER_FIELDS = re.compile(r"^transducer\.(max_voltage|band\.[01]|gain_pa_per_v\.\d+|gain_frequencies\.\d+"
                                r"|gain_uncertainty)$")


def drive_fields_vectorised(path: str) -> bool:
    """A program or transducer field whose checks :func:`check_drives` gives per point."""
    if path.startswith("transducer."):
        return bool(_TRANSDUCER_FIELDS.match(path))
    m = _STEP.match(path)
    return bool(m and _STEP_FIELDS.match(m.group("rest")))


def check_drives(batch) -> None:
    """The resolver's checks of the transducer and the programs' drives, vectorised over the points of
    ``batch`` (in place; geometry codes found earlier win, as in :func:`check_points`).

    Per point, as the resolver: the transducer is built first (max_voltage positive E401 and at most
    MAX_TRANSDUCER_VOLTAGE E502, band from a positive frequency E401, gain table increasing with
    non-negative gains E413, gain_uncertainty in range E320); then each program step (amplitudes not
    negative E401, limits and slew positive E401, a drive's amplitudes within its limit E502,
    durations positive E503, margins in 1 .. MAX_MARGIN E505, hold bounds positive E401); a program
    with a failed step and a failed transducer are left out of the program-vs-transducer checks
    (frequency in the band E501, amplitude or limit above the transducer's maximum E502).  Of several
    errors the one the resolver reports first (sorted by location) is kept.
    """
    from acl.design.builders import MAX_GAIN_UNCERTAINTY, MAX_TRANSDUCER_VOLTAGE
    from acl.design.programs import MAX_MARGIN

    d = batch.design
    moved = [p for p in batch.fields if p.startswith(("programs.", "transducer."))]
    if not moved or not batch.n:
        return
    g = batch.get
    n = batch.n
    found: list[tuple[tuple, np.ndarray, str]] = []       # (location, failing points, code)

    def where(span) -> tuple:
        return (span.file, span.line, span.column) if span is not None else ("", 0, 0)

    tr = d.transducer
    tr_ok = np.ones(n, bool)
    if tr is not None:
        loc = where(tr.span)
        base = "transducer."
        vmax = g(base + "max_voltage")
        lo_band = g(base + "band.0")
        fs = np.stack([g(f"{base}gain_frequencies.{k}") for k in range(len(tr.gain_frequencies))], axis=1)
        gs = np.stack([g(f"{base}gain_pa_per_v.{k}") for k in range(len(tr.gain_pa_per_v))], axis=1)
        flat = tr.gain_frequencies == (1.0,)             # `gain = 230 Pa/V`: a constant, no table checks
        stages = [(~((vmax > 0) & np.isfinite(vmax)), "E401"), (vmax > MAX_TRANSDUCER_VOLTAGE, "E502"),
                  (lo_band <= 0, "E401")]
        if not flat:
            stages += [(np.any(np.diff(fs, axis=1) <= 0, axis=1), "E413"),
                       (np.any((gs < 0) | ~np.isfinite(gs), axis=1) | np.any(fs <= 0, axis=1), "E413")]
        if tr.gain_uncertainty is not None:
            u = g(base + "gain_uncertainty")
            stages.append((~(np.isfinite(u) & (u >= 0) & (u <= MAX_GAIN_UNCERTAINTY)), "E320"))
        code = np.full(n, "", dtype="<U8")
        for bad, c in stages:                            # the builder stops at the first failing key
            code = np.where((code == "") & bad, c, code)
        tr_ok = code == ""
        for c in np.unique(code[~tr_ok]):
            found.append((loc, code == c, str(c)))
    for p in d.programs:
        prog_ok = np.ones(n, bool)
        checks = []                                      # program-vs-transducer checks of this program
        for i, st in enumerate(p.steps):
            base = f"programs.{p.name}.steps.{i}."
            loc = where(st.span)
            stages = []
            lim = g(base + "limits.max_voltage") if getattr(getattr(st, "limits", None), "max_voltage", None) is not None else None
            if st.kind == "drive":
                amps = np.stack([g(f"{base}drive.tones.{j}.amplitude") for j in range(len(st.drive.tones))], axis=1) \
                    if st.drive.tones else np.zeros((n, 0))
                stages.append((np.any(amps < 0, axis=1), "E401"))
                total = amps.sum(axis=1)
                if lim is not None:
                    stages += [(lim <= 0, "E401")]
                if getattr(st, "limits", None) is not None and st.limits.slew_rate is not None:
                    stages.append((g(base + "limits.slew_rate") <= 0, "E401"))
                if lim is not None:
                    stages.append((total > lim * (1 + 1e-9), "E502"))
                stages.append((~(g(base + "duration") > 0), "E503"))
                volts = total
            elif st.kind == "sweep":
                amp = g(base + "amplitude")
                stages += [(amp < 0, "E401"), (~(g(base + "duration") > 0), "E503")]
                volts = amp
            else:
                # the order of acl.design.programs._step: follow (duration, limits), switch (margin,
                # limits), hold (bound, margin, duration, limits), pause (duration)
                if st.kind == "hold" and st.bound is not None:
                    stages.append((g(base + "bound") <= 0, "E401"))
                if st.kind in ("switch", "hold"):
                    m = g(base + "margin")
                    stages += [(m < 1, "E505"), (m > MAX_MARGIN, "E505")]
                if st.kind != "switch" and getattr(st, "duration", None) is not None:
                    stages.append((~(g(base + "duration") > 0), "E503"))
                if lim is not None:
                    stages.append((lim <= 0, "E401"))
                if getattr(st, "limits", None) is not None and st.limits.slew_rate is not None:
                    stages.append((g(base + "limits.slew_rate") <= 0, "E401"))
                volts = lim
            code = np.full(n, "", dtype="<U8")
            for bad, c in stages:
                code = np.where((code == "") & bad, c, code)
            for c in np.unique(code[code != ""]):
                found.append((loc, code == c, str(c)))
            prog_ok &= code == ""
            if tr is not None and volts is not None:
                checks.append((loc, volts, st))
        # acl.design.checks.check_programs: only for a built transducer and a built program
        if tr is None:
            continue
        live = prog_ok & tr_ok
        band_lo, band_hi, vmax = g("transducer.band.0"), g("transducer.band.1"), g("transducer.max_voltage")
        for st in p.steps:
            freqs, _ = C.step_tones(st)
            loc = where(st.span)
            out_band = np.zeros(n, bool)
            for f in freqs:
                out_band |= ~((band_lo * (1 - 1e-9) <= f) & (f <= band_hi * (1 + 1e-9)))
            found.append((loc, live & out_band, "E501"))
            for _loc, volts, st2 in checks:
                if st2 is st:
                    found.append((loc, live & (volts > vmax * (1 + 1e-9)), "E502"))
    # the resolver sorts its errors by location; builder errors precede check errors at one location
    order = sorted(range(len(found)), key=lambda k: (found[k][0], k))
    for k in order:
        _mark(batch, found[k][1], found[k][2])
