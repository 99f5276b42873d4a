"""Synthetic measurements from the fit's own forward model, with chosen effects and Gaussian noise.

The same model `acl fit` uses (acl.fit.forward), so a user can check that an analysis finds an
effect planted in data shaped like their experiment.  The experiment is the cartesian product of
override sets x frequencies x voltages, repeated ``repeats`` times; rows are timed ``interval``
apart in that order; every declared observable (or the chosen ones) is measured on every row.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from acl.diagnostics import DiagnosticError, Span, error, suggest

# user-facing effect parameters that are the inverse of the fitted coordinate
ALIASES = {"v_sat": ("inv_vsat2", lambda v: 1.0 / v**2), "plateau": ("inv_plateau", lambda v: 1.0 / v)}


@dataclass
class Experiment:
    frequencies: tuple = (125e3,)           # Hz
    voltages: tuple = tuple(np.linspace(0, 8, 9))   # V peak
    sets: dict | None = None                # NAME -> list of override strings
    repeats: int = 1
    interval: float = 1.0                   # s between rows
    observables: tuple = ()                 # empty: every declared observable
    label: str = ""                         # `experiment` column of its rows (several experiments, one data set)


def effect_inputs(spec: dict) -> dict:
    """{effect: {param: SI value}} with aliases (v_sat, plateau) turned into fitted coordinates; checked."""
    from acl.fit.effects import EFFECTS

    out = {}
    for eid, params in spec.items():
        if eid not in EFFECTS:
            raise DiagnosticError([error("E-USAGE", f"unknown effect `{eid}`", Span(file="<--effect>", line=1, column=1),
                                         suggest(eid, EFFECTS) or f"effects: {', '.join(EFFECTS)}")])
        eff = EFFECTS[eid]
        names = [p.name for p in eff.params]
        vals = {p.name: (p.null if p.null == p.null else p.start) for p in eff.params}
        for k, v in params.items():
            if k in ALIASES and ALIASES[k][0] in names:
                vals[ALIASES[k][0]] = ALIASES[k][1](v)
            elif k in names:
                vals[k] = v
            else:
                raise DiagnosticError([error("E-USAGE", f"effect `{eid}` has no parameter `{k}`",
                                             Span(file="<--effect>", line=1, column=1),
                                             f"parameters: {', '.join(names + [a for a, (t, _) in ALIASES.items() if t in names])}")])
        out[eid] = vals
    return out


def generate(design_path, experiment, effects: dict | None = None, noise: float = 0.0,
             seed: int = 0, coeffs: dict | None = None, search_paths=()):
    """Return (Dataset, Prepared) of synthetic rows (values in SI, sigma = noise).

    ``experiment``: one :class:`Experiment` or a list of them (run one after the other, in one data set,
    rows tagged with each experiment's ``label``: e.g. a pair and its calibration beam)."""
    import acl
    from acl.fit.data import Dataset
    from acl.fit.forward import predict, prepare
    from acl.fit.mechanism import build_instance

    design = acl.load(design_path, search_paths=search_paths)
    experiments = [experiment] if isinstance(experiment, Experiment) else list(experiment)
    set_names = sorted({k for ex in experiments for k in (ex.sets or {})})
    rows, times = [], []
    t = 0.0
    for ex in experiments:
        obs = list(ex.observables) or [o.name for o in design.observes]
        for name in obs:
            design.observe(name)
        sets = ex.sets or {}
        names = sorted(sets)
        combos = list(itertools.product(*[sets[k] for k in names])) or [()]
        for _ in range(max(1, ex.repeats)):
            for combo in combos:
                cell = dict(zip(names, combo))
                for f in ex.frequencies:
                    for v in ex.voltages:
                        for name in obs:
                            rows.append((name, tuple(cell.get(k, "") for k in set_names),
                                         ((float(f), float(v)),) if v > 0 else (), ex.label))
                            times.append(t)
                            t += float(ex.interval)
    n = len(rows)
    from acl.fit.data import parse_quantity

    set_arr = {k: np.array([r[1][j] for r in rows], dtype=object) for j, k in enumerate(set_names)}
    set_si = {k: np.array([parse_quantity(x)[0] if x else np.nan for x in set_arr[k]], float) for k in set_names}
    data = Dataset(np.array([r[0] for r in rows], dtype=object), np.zeros(n), np.full(n, float(noise) or np.nan),
                   np.array(times, float), [r[2] for r in rows], set_arr, set_si,
                   [Span(file="<synth>", line=i + 2, column=1) for i in range(n)], np.array(["um"] * n, dtype=object),
                   experiment=np.array([r[3] for r in rows], dtype=object))
    cache: dict = {}

    def load_instance(key):
        if key not in cache:
            cache[key] = build_instance(acl.load(design_path, overrides=dict(key), search_paths=search_paths)
                                        if key else design)
        return cache[key]

    # coefficients in ``coeffs`` (gamma, alpha) refer to f_ref of these rows: the most common frequency
    P = prepare(data, load_instance)
    y = predict(P, dict(coeffs or {}), effect_inputs(effects or {}))
    rng = np.random.default_rng(seed)
    data.value = y + rng.normal(0.0, noise, n) if noise > 0 else y
    return data, P


def write_csv(data, path, unit: str = "um") -> None:
    """Write a data set in the documented CSV format (atomically)."""
    import os

    from acl.fit.drive import format_drive
    from acl.units import parse_unit

    factor, _ = parse_unit(unit)
    set_names = sorted(data.sets)
    with_sigma = bool(np.all(np.isfinite(data.sigma)))     # noise-free data have no sigma column
    with_exp = bool(np.any(data.experiment != ""))
    head = ["observable", "value", "unit", "drive", "time", *(["sigma"] if with_sigma else []),
            *(["experiment"] if with_exp else []), *[f"set:{k}" for k in set_names]]
    lines = [",".join(head)]
    for i in range(data.n):
        cells = [data.observable[i], f"{data.value[i] / factor:.6g}", unit, format_drive(data.tones[i]),
                 f"{data.time[i]:.6g}", *([f"{data.sigma[i] / factor:.6g}"] if with_sigma else []),
                 *([data.experiment[i]] if with_exp else []),
                 *[data.sets[k][i] for k in set_names]]
        lines.append(",".join(cells))
    tmp = f"{path}.tmp{os.getpid()}"
    with open(tmp, "w", encoding="utf-8") as fh:
        fh.write("\n".join(lines) + "\n")
    os.replace(tmp, path)
