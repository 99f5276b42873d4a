"""One sweep, end to end: spec -> the map parameters -> fields (once) -> chunks (sample, perturb,
evaluate) on a scheduler -> the table.  Shared by ``acl.sweep(...)`` and ``acl sweep``."""
from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from acl.design.model import Design
from acl.diagnostics import DiagnosticError, Span, error
from acl.sweep.perturb import FieldMap, field_batch, field_map
from acl.sweep.sample import chunk_points, chunk_range
from acl.sweep.spec import SweepSpec
from acl.sweep.table import SweepTable, assemble
from acl.sweep.validity import mark_outside_free_ranges, without_free_ranges


@dataclass(frozen=True)
class ChunkTask:
    """``task(k)``: the columns of chunk k (picklable, so a dask worker can run it)."""

    design: Design
    spec: SweepSpec
    fmap: FieldMap
    quantities: tuple[str, ...]
    at: str | None = None

    def __call__(self, k: int) -> dict[str, np.ndarray]:
        from acl.sweep.evaluate import evaluate

        spec = self.spec
        start, stop = chunk_range(spec, k, spec.chunk_size)
        pts = chunk_points(spec, k, spec.chunk_size)
        # one rule with acl tune: a `free` range bounds the grid's or nominal value, not the print about it
        batch = field_batch(without_free_ranges(self.design), pts, self.fmap)
        mark_outside_free_ranges(batch, self.design, chunk_points(spec, k, spec.chunk_size, spread=False))
        cols = evaluate(batch, list(self.quantities), self.at)
        return {"point": np.arange(start, stop, dtype=np.int64), **pts, "valid": batch.valid.copy(),
                "code": batch.code.copy(), **cols}


def left_out(design: Design, at: str | None = None) -> list[str]:
    """One note per kind of column the batched evaluation leaves out for ``design`` (its quantity families and
    lint rules), each with its reason.  Without it a design with declared effects lost its deflection, snap-in,
    force and latch columns silently (issue 23): a column that is absent must be named."""
    from acl.sweep.evaluate import supported

    _, missing = supported(design, at)
    absent = set()                           # families this design would not have anyway
    if not design.latches:
        absent |= {"switching_force_", "release_force_", "bistable_", "margin_"}
    if len(design.capsules) < 2:
        absent |= {"force_", "attract_", "phase_", "critical_distance_", "snap_in_"}
    by_reason: dict[str, list[str]] = {}
    for key, why in missing.items():
        if key.startswith("require_") or key in absent:
            continue                          # requires: reported one by one (unevaluated)
        name = key.rstrip("_") + ("*" if key.endswith("_") else "")
        by_reason.setdefault(why, []).append(name)
    return [f"columns not computed: {', '.join(names)}: {why}" for why, names in by_reason.items()]


def choose_quantities(design: Design, quantities=None, at: str | None = None) -> tuple[list[str], dict[str, str]]:
    """(columns to compute, {require_i: why not evaluated}); unknown names raise DiagnosticError."""
    from acl.sweep.evaluate import supported

    names, missing = supported(design, at)
    unevaluated = {k: f"{k} (`{design.requires[int(k.split('_')[1]) - 1].text}`): {why}"
                   for k, why in missing.items() if k.startswith("require_")}
    if quantities is None:
        return names, unevaluated
    wanted = list(dict.fromkeys(quantities))
    need = [f"require_{i}_pass" for i in range(1, len(design.requires) + 1)]
    bad = [q for q in wanted if q not in names]
    if bad:
        from acl.diagnostics import suggest

        raise DiagnosticError([error("E-USAGE", f"--quantity {q}: not available for this design", Span(file="<--quantity>", line=1, column=1),
                                     suggest(q, names) or ("available: " + ", ".join(names)))
                               for q in bad])
    return wanted + [c for c in need if c in names and c not in wanted], unevaluated


# Columns that do not read the design's programs or transducer (acl.sweep.evaluate reads those from
# the nominal design: a column name carries a program frequency).
_PROGRAM_FREE = ("resonance_", "q_")


def _nominal_program_only(design: Design, fmap: FieldMap, cols: list[str], explicit: bool) -> tuple[list[str], dict[str, str]]:
    """Drop (or, when asked for by name, refuse) columns that would silently use the nominal program
    or transducer while a swept parameter moves them."""
    from acl.sweep.validity import drive_fields_vectorised

    # drive amplitudes, limits and the transducer's values are read per point (acl.sweep.evaluate);
    # a moving tone frequency (it names columns) or follow path is not
    moving = sorted(p for p in [*fmap.linear, *fmap.exact] if p.startswith(("programs.", "transducer."))
                    and not drive_fields_vectorised(p))
    if not moving:
        return cols, {}
    keep_requires = {f"require_{i}_{k}" for i, r in enumerate(design.requires, 1) if r.kind in ("resonance", "separation")
                     for k in ("value", "pass")}
    why = (f"a swept parameter moves `{moving[0]}`" + (f" and {len(moving) - 1} more program/transducer field(s)" if len(moving) > 1 else "")
           + ": the batched forces, margins, gaps and lint rules take the programs' frequencies from the design")
    if all(f"require_{i}_pass" in keep_requires for i in range(1, len(design.requires) + 1)):
        keep_requires.add("requires_pass")
    bad = [c for c in cols if not (c.startswith(_PROGRAM_FREE) or c in keep_requires)]
    if bad and explicit:
        requested = [c for c in bad if not c.startswith("require")]
        if requested:
            raise DiagnosticError([error("E-USAGE", f"--quantity {requested[0]}: {why}", Span(file="<--quantity>", line=1, column=1),
                                         "sweep resonances and Q only, or keep the program's values fixed")])
    return [c for c in cols if c not in bad], {c: why for c in bad}


def run_sweep(design: Design, spec: SweepSpec, quantities=None, at: str | None = None, scheduler: str | None = None,
              progress=None, overrides=None, search_paths=(), timeout: float | None = None, notify=None) -> SweepTable:
    """Evaluate every point of ``spec`` on ``design`` (loaded from ``design.file`` with ``overrides``);
    ``timeout``/``notify``: a cluster without workers (acl.sweep.run.map_chunks)."""
    from acl.sweep.run import map_chunks

    cols, unevaluated = choose_quantities(design, quantities, at)
    fmap = field_map(design, spec.names, spec.box(), overrides=overrides, search_paths=search_paths, seed=spec.seed)
    cols, dropped = _nominal_program_only(design, fmap, cols, quantities is not None)
    for i, r in enumerate(design.requires, 1):
        if f"require_{i}_pass" in dropped:
            unevaluated[f"require_{i}"] = f"require_{i} (`{r.text}`): {dropped[f'require_{i}_pass']}"
    task = ChunkTask(design, spec, fmap, tuple(cols), at)
    parts = map_chunks(task, spec.n_chunks, scheduler, progress, timeout, notify)
    order = ["point", *spec.names, "valid", "code", *cols]
    units = {n: spec.units[n] for n in spec.names}
    notes = list(spec.notes) + list(fmap.notes)
    if quantities is None:
        notes += left_out(design, at)
    if dropped and quantities is None:
        notes.append(f"{len(dropped)} column(s) left out: " + next(iter(dropped.values())))
    notes += [why for why in unevaluated.values()]
    from acl.sweep.evaluate import per_point_names

    slow = [c for c in cols if c in per_point_names(design, at)]
    if slow:
        notes.append(f"{len(slow)} column(s) computed point by point by `acl analyze`'s engine, with the declared "
                     f"effects applied ({', '.join(slow[:4])}{', ...' if len(slow) > 4 else ''}): about 0.1 s per point")
    data = assemble(parts, order)
    notes += model_form_notes(data)
    if quantities is not None and any(r.kind in ("margin", "gap") for r in design.requires) and "model_form_uncertain" not in cols \
            and "model_form_uncertain" in choose_quantities(design, None, at)[0]:
        notes.append("the yield's interval is not widened by the model-form uncertainty past the validity limits: "
                     "add --quantity model_form_uncertain (acl.sweep.model_form)")
    return SweepTable(data, spec, units=units, notes=notes, unevaluated=unevaluated,
                      n_requires=len(design.requires), field_map=fmap,
                      force_requires=tuple(i for i, r in enumerate(design.requires, 1) if r.kind in ("margin", "gap")))


def model_form_notes(data) -> list[str]:
    """A note on the points past a soft validity limit (acl.sweep.model_form), when there are any, and one on the
    first-principles pair force's spread where the table has its column."""
    if data.dtype.names is None or "model_form_rel" not in data.dtype.names:
        return []
    out = []
    if "model_form_pair_uncertain" in data.dtype.names:
        from acl.physics import constants as C

        k = int(np.count_nonzero(data["valid"] & data["model_form_pair_uncertain"]))
        out.append(f"the design's pair forces are acl's first-principles values (no bjerknes_scale): the paper's measured "
                   f"pairs attracted {min(r for _, r in C.PAIR_SCALE_ROWS):.3g}-{max(r for _, r in C.PAIR_SCALE_ROWS):.3g}x "
                   f"harder ({C.PAIR_SCALE_DISTRIBUTION}; fitted median {C.FIRST_PRINCIPLES_PAIR_SCALE_MEDIAN:.3g}; "
                   f"acl.physics.constants.PAIR_SCALE_ROWS); {k} of {len(data)} points have a margin or gap verdict that "
                   f"differs at its 2.5 or 97.5 % quantile ({C.pair_scale_quantile(0.025):.2g}x or "
                   f"{C.pair_scale_quantile(0.975):.3g}x), and the yield's interval counts them both ways "
                   "(model_form_pair_uncertain); calibrate the pair force on measured pairs (acl fit) to narrow it")
        if "model_form_pair_median_pass" in data.dtype.names:
            m = int(np.count_nonzero(data["valid"] & data["model_form_pair_median_pass"]))
            out[-1] += (f"; at its median {C.FIRST_PRINCIPLES_PAIR_SCALE_MEDIAN:.3g}x, {m} of {len(data)} points pass "
                        "every margin and gap require (model_form_pair_median_pass)")
    rel = np.where(data["valid"], data["model_form_rel"], 0.0)
    past = int(np.count_nonzero(rel > 0))
    if not past:
        return out
    unc = (int(np.count_nonzero(data["valid"] & data["model_form_uncertain"]))
           if "model_form_uncertain" in data.dtype.names else 0)
    return out + [(f"{past} of {len(data)} points are past a soft validity limit (interface amplitude eps/R > 0.25 or pair "
            f"distance < 2 x the orifice radii: acl.physics.validity): their forces carry a model-form uncertainty up "
            f"to {float(rel.max()):.0%} (column model_form_rel); {unc} of them have a margin or gap verdict it could "
            "flip, and the yield's interval counts them both ways (model_form_uncertain)")]


def sweep(design, vary=None, tolerance=None, n=None, seed=0, quantities=None, at=None, scheduler=None,
          overrides=None, search_paths=(), chunk_size=None, progress=None) -> SweepTable:
    """The Python API behind ``acl.sweep`` (its docstring)."""
    from acl.sweep.spec import CHUNK_SIZE, build_spec

    if isinstance(design, Design):
        if overrides:
            raise DiagnosticError([error("E-USAGE", "overrides: give the design as a path when overriding parameters",
                                         Span(file="<overrides>", line=1, column=1))])
        d = design
    else:
        from acl.design.resolve import load_design

        d = load_design(str(design), overrides=dict(overrides or {}), search_paths=search_paths)
    spec = build_spec(d, vary, tolerance, n, seed, chunk_size or CHUNK_SIZE)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        table = run_sweep(d, spec, quantities, at, scheduler, progress, overrides, search_paths)
    for note in table.notes:
        if "nonlinear" in note:
            from acl.sweep.perturb import SweepWarning

            warnings.warn(note, SweepWarning, stacklevel=3)
    return table


def scaled(spec: SweepSpec, factor: float) -> SweepSpec:
    """The same sweep with every spread's deviation multiplied by ``factor`` (the same random draws)."""
    from dataclasses import replace

    from acl.design.model import Spread
    from acl.sweep.spec import Tolerance

    tols = tuple(Tolerance(t.name, Spread(kind=t.spread.kind, a=t.spread.a * factor, b=t.spread.b * factor,
                                          relative=t.spread.relative), t.unit, t.source) for t in spec.tolerances)
    return replace(spec, tolerances=tols)


def yield_vs_tolerance(design: Design, spec: SweepSpec, scales, quantities=None, at=None, scheduler=None,
                       overrides=None, search_paths=()) -> list[dict]:
    """Yield of ``spec`` with its spreads scaled by each factor in ``scales`` (common random numbers:
    the same seed, so the curve is smooth); rows {scale, yield, lower, upper, passed, total}."""
    rows = []
    for s in scales:
        t = run_sweep(design, scaled(spec, float(s)), quantities, at, scheduler, None, overrides, search_paths)
        y = t.yields().get("all")
        if y is None:
            raise DiagnosticError([error("E-USAGE", "yield vs tolerance: " + "; ".join(t.unevaluated.values()),
                                         Span(file="<--tolerance-scales>", line=1, column=1))])
        rows.append({"scale": float(s), **y.as_dict()})
    return rows
