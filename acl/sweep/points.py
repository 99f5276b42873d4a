"""Columns of a sweep that the analysis engine gives point by point: the families that declared effects
change (forces at rest, the latch law, the equilibria and snap-in), for the designs that declare effects the
batched evaluation does not model (one without a ``sweep`` place in acl.physics.effect_table: every effect of
the table has one today, so this is the fallback for an effect added later; tests/test_sweep_points.py checks it
against the batched engine).

Before, :func:`acl.sweep.evaluate.supported` left these columns out of the table of a design with declared
effects (a calibrated design from `acl fit --calibrated` lost its deflection and snap-in columns, issue 23).
Here every valid point is materialised (:func:`acl.sweep.perturb.materialize`) and analysed by the same
function as `acl analyze` (:func:`acl.analysis.report.analyze`, the engine at batch size 1), so each column
equals the `acl analyze --output-format json` field that :data:`acl.sweep.evaluate.QUANTITIES` names, with
every declared effect applied.  The cost is one analysis per point (about 0.1 s for the Fig. 4 pair), so
the sweep adds a note saying which columns come this way.
"""
from __future__ import annotations

import re

import numpy as np

from acl.design import model as M

# column families a declared effect changes (acl.sweep.evaluate._effect_blocks) and that analyze reports
REST_FAMILIES = ("force_", "attract_", "phase_", "critical_distance_")
LATCH_FAMILIES = ("switching_force_", "release_force_", "bistable_", "margin_")
MOTION_FAMILIES = ("snap_in_", "tip_deflection", "deflection_", "equilibrium_ok")


def _fkey(f: float) -> str:
    return f"{f / 1e3:g}khz".replace(".", "p")


def _ident(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_]", "_", name)


def _pairs(design: M.Design) -> list[tuple[str, str]]:
    names = [c.name for c in design.capsules]
    return [(a, b) for i, a in enumerate(names) for b in names[i + 1:]]


def _deflected(design: M.Design) -> list[tuple[str, str]]:
    """(name, kind) of the deflections analyze reports at a drive (acl.analysis.mechanics.build_mechanism)."""
    from acl.analysis.mechanics import build_mechanism

    mech = build_mechanism(design)
    out = [(el.name, el.kind) for el in mech.elements]
    out += [(name, "link") for (_k, _n, _a, _b, name) in mech.links if name not in {n for n, _ in out}]
    return out


def columns(design: M.Design, blocks: dict[str, list[str]], at: str | None) -> dict[str, list[str]]:
    """{family: column names} given point by point for the families that ``blocks`` (effects per family:
    'rest', 'latch', 'motion') take from the batched evaluation."""
    from acl.analysis.report import program_frequencies, step_drives

    freqs = program_frequencies(design) or []
    pairs = _pairs(design)
    out: dict[str, list[str]] = {}
    if blocks["rest"]:
        for fam, suffix in zip(REST_FAMILIES, ("_n", "", "_deg", "_m")):
            out[fam] = [f"{fam}{_ident(a)}_{_ident(b)}_{_fkey(f)}{suffix}" for f in freqs for a, b in pairs]
    if blocks["latch"] and design.latches:
        out["switching_force_"] = [f"switching_force_{_ident(lt.name)}_n" for lt in design.latches]
        out["release_force_"] = [f"release_force_{_ident(lt.name)}_n" for lt in design.latches]
        out["bistable_"] = [f"bistable_{_ident(lt.name)}" for lt in design.latches]
        out["margin_"] = [f"margin_{_ident(lt.name)}_{_ident(p.name)}_{i + 1}" for lt in design.latches
                          for p, i, _st, _d in step_drives(design)]
    if blocks["motion"]:
        if pairs and freqs:
            out["snap_in_"] = [f"snap_in_{_ident(a)}_{_ident(b)}_{_fkey(f)}_v" for f in freqs for a, b in pairs]
        if at is not None and any((design.mount_of(c.name) or M.Fix(capsule="", span=c.span)).kind == "mount"
                                  for c in design.capsules):
            defl = _deflected(design)
            out["tip_deflection"] = [f"tip_deflection_{_ident(n)}_m" for n, kind in defl if kind == "beam"]
            out["deflection_"] = [f"deflection_{_ident(n)}_m" for n, kind in defl if kind != "beam"]
            out["equilibrium_ok"] = ["equilibrium_ok"]
    return {k: v for k, v in out.items() if v}


def _value(v) -> float:
    return float("nan") if v is None else float(v)


def _extract(design: M.Design, rep, wanted: list[str]) -> dict[str, float | bool]:
    """The values of ``wanted`` columns from one analysis report (the fields QUANTITIES names)."""
    row: dict[str, float | bool] = {}
    for pf in rep.pairs:
        tag = f"{_ident(pf['a'])}_{_ident(pf['b'])}_{_fkey(pf['frequency_hz'])}"
        row[f"force_{tag}_n"] = _value(pf["force_n"])
        row[f"attract_{tag}"] = bool(pf["attract"])
        row[f"phase_{tag}_deg"] = _value(pf["phase_difference_deg"])
        row[f"critical_distance_{tag}_m"] = _value(pf["critical_distance_eq3_m"])
        row[f"snap_in_{tag}_v"] = _value(pf["snap_in_voltage_v"])
    for lt in rep.latches or []:
        key = _ident(lt["name"])
        row[f"switching_force_{key}_n"] = _value(lt.get("switching_force_n"))
        row[f"release_force_{key}_n"] = _value(lt.get("release_force_n"))
        row[f"bistable_{key}"] = bool(lt.get("bistable"))
        for m in lt["margins"]:
            row[f"margin_{key}_{_ident(m['program'])}_{m['step']}"] = _value(m["margin"])
    eq = rep.equilibrium
    if eq:
        ok = eq["status"] == "ok"
        row["equilibrium_ok"] = ok
        for name, v in eq["deflections_m"].items():
            # NaN where the equilibrium is lost (snap-in, no convergence), as the batched columns
            row[f"tip_deflection_{_ident(name)}_m"] = row[f"deflection_{_ident(name)}_m"] = float(v) if ok else np.nan
    for i, r in enumerate(rep.requires, 1):
        row[f"require_{i}_value"] = _value(r.get("value"))
        row[f"require_{i}_pass"] = bool(r.get("ok"))
    return {k: row.get(k, np.nan) for k in wanted}


def evaluate_points(batch, wanted: list[str], at: str | None) -> dict[str, np.ndarray]:
    """One column (n,) per name in ``wanted``: each valid point of ``batch`` analysed by `acl analyze`'s
    engine (invalid points: NaN, or False for pass/fail columns)."""
    from acl.analysis.report import analyze
    from acl.sweep.perturb import materialize

    drive = None
    if at is not None:
        from acl.design.drives import drive_from_text

        drive = drive_from_text(at, "<at>")
    snap = any(q.startswith("snap_in_") for q in wanted)
    rows: dict[int, dict] = {}
    for i in np.flatnonzero(np.asarray(batch.valid, bool)):
        d = materialize(batch, int(i))
        rep = analyze(d, drive if any(q.startswith(("tip_deflection", "deflection_", "equilibrium_ok")) for q in wanted)
                      else None, snap_in=snap)
        rows[int(i)] = _extract(d, rep, wanted)
    out = {}
    for q in wanted:
        boolean = q.startswith(("attract_", "bistable_", "equilibrium_ok")) or q.endswith("_pass")
        col = np.zeros(batch.n, bool) if boolean else np.full(batch.n, np.nan)
        for i, row in rows.items():
            v = row[q]
            col[i] = bool(v) if boolean and not (isinstance(v, float) and np.isnan(v)) else (False if boolean else v)
        out[q] = col
    return out
