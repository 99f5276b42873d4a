"""Latch margins, `require`s and the lint rules a sweep reports, batched over its points.

The lint rules here are copies of acl/lint/rules (ACL101-105, 201, 401, 402, 501-504, 603) over the batched
results, with the default thresholds and before suppressions; tests/test_sweep_drives.py keeps them equal to
the rules on perturbed points and on every example.  To be replaced by the rules run on the engine's batched
results (issue 23)."""
from __future__ import annotations

import math

import numpy as np

from acl.physics import batch as PB
from acl.physics import constants as C
from acl.physics.forces import critical_distance
from acl.physics.limits import clamp_strain, eq1_limit_ratio, interface_cap_volume, modes_overlap
from acl.physics.transducer import pressure_per_volt_rows
from acl.sweep.columns import QuantityError, _pairs
from acl.sweep.pair_mechanics import PairMechanics


class Checks(PairMechanics):
    """Latches, requires and lint rules on top of the equilibria."""

    def latch(self, name: str) -> dict:
        """Switching and release forces of latch ``name`` per point and its margin at every program step
        (mechanics.latch_margins as analyze calls it: the shuttle's capsules and those trussed to them, every latch in
        the state the program's earlier steps leave it, per point)."""
        return self.latches_all()[name]

    def latches_all(self) -> dict:
        def build():
            from acl.analysis.mechanics import latch_carried
            from acl.physics.latch import latch_landscape

            lats = {}
            for lt in self.design.latches:
                base = f"latches.{lt.name}"
                geo = [self.get(f"{base}.{k}") for k in ("angle", "length", "width", "thickness", "youngs_modulus")]
                geo[4] = geo[4] * self.e_scale()      # a declared stiffness_scale (mechanics.latch_geometry)
                fsw, rel, bistable = PB.latch_switching_force(*geo)
                axis = np.asarray(lt.axis, float)
                lats[lt.name] = {"switching": fsw, "release": rel, "bistable": bistable, "margins": {},
                                 "geo": [np.broadcast_to(np.asarray(g, float), (self.n,)) for g in geo],
                                 "axis": axis / np.linalg.norm(axis), "travel": None,
                                 "carried": [self.caps.index(self.design.capsule(c)) for c in latch_carried(self.design, lt)]}
            lay = self.layout()
            program, flipped = None, {}
            for p, i, _st, freqs, volts in self.step_drives():
                if p is not program:           # each program starts from the declared states
                    program, flipped = p, {lt.name: np.zeros(self.n, bool) for lt in self.design.latches}
                pos = lay["rest"]
                for lt in self.design.latches:
                    lat = lats[lt.name]
                    if not flipped[lt.name].any():
                        continue
                    if lat["travel"] is None:   # state b travel per point (latch_landscape, as analyze)
                        tr = [latch_landscape(*(float(g[k]) for g in lat["geo"])).state_b for k in range(self.n)]
                        lat["travel"] = np.array([np.nan if x is None else x for x in tr], float)
                    shift = np.where(flipped[lt.name] & np.isfinite(lat["travel"]), np.nan_to_num(lat["travel"]), 0.0)
                    shift = shift * (1.0 if lt.state == "a" else -1.0)
                    pos = np.array(pos, float, copy=True)
                    for c in lat["carried"]:
                        pos[:, c] = pos[:, c] + shift[:, None] * lat["axis"]
                F = self.forces(pos, freqs, volts)
                for lt in self.design.latches:
                    lat = lats[lt.name]
                    push = sum((F[:, c] @ lat["axis"] for c in lat["carried"]), np.zeros(self.n))
                    in_a = (lt.state == "a") != flipped[lt.name]
                    required = np.where(in_a, lat["switching"],
                                        np.where(lat["bistable"], np.nan_to_num(lat["release"]), 0.0))
                    avail = np.where(in_a, push, -push)
                    m = np.where(required > 0, avail / np.where(required > 0, required, 1.0), np.inf)
                    lat["margins"][(p.name, i)] = m
                    flipped[lt.name] = flipped[lt.name] ^ (m >= 1.0)
            return lats
        return self.once(("latches",), build)

    # -- requires and lint ------------------------------------------------------------------------------
    def require(self, i: int) -> tuple[np.ndarray, np.ndarray]:
        from acl.analysis.report import step_drives

        r = self.design.requires[i - 1]
        idx = {c.name: k for k, c in enumerate(self.caps)}
        if r.kind == "resonance":
            f = self.modes(idx[r.args[0]])[0]
            value = f[:, r.mode] if r.mode < f.shape[1] else np.full(self.n, np.nan)
        elif r.kind == "separation" and len(r.args) == 1:      # closest adjacent modes of one capsule
            f = np.sort(self.modes(idx[r.args[0]])[0], axis=1)     # NaN (mode not reported) sorts last
            if f.shape[1] < 2:
                value = np.full(self.n, np.nan)
            else:
                gaps = np.diff(f, axis=1)
                gaps = np.where(np.isfinite(gaps), gaps, np.inf).min(axis=1)
                value = np.where(np.isfinite(gaps), gaps, np.nan)
        elif r.kind == "separation":
            value = np.abs(self.modes(idx[r.args[0]])[0][:, 0] - self.modes(idx[r.args[1]])[0][:, 0])
        elif r.kind == "margin":
            lat = self.latch(r.args[0])
            steps = list(step_drives(self.design))
            intended = [lat["margins"][(p.name, k)] for p, k, st, _d in steps
                        if st.kind == "switch" and st.latch == r.args[0]]
            allm = [lat["margins"][(p.name, k)] for p, k, _st, _d in steps]
            if intended:
                value = np.min(intended, axis=0)
            elif allm:
                value = np.max(allm, axis=0)
            else:
                value = np.full(self.n, np.nan)
        elif r.kind == "gap":
            value = self.gap_over_steps(r.args[0], r.args[1])
        else:
            raise QuantityError("E-SWEEP-Q02", f"`{r.text}` is not batched")
        ok = np.isfinite(value) | np.isinf(value)
        ok &= ~np.isnan(value)
        if r.lower is not None:      # bounds may follow a swept parameter (`in f0 - 5 kHz .. f0 + 5 kHz`)
            ok &= value >= self.get(f"requires.{i - 1}.lower")
        if r.upper is not None:
            ok &= value <= self.get(f"requires.{i - 1}.upper")
        return value, ok

    def lint(self, code: str) -> np.ndarray:
        from acl.lint.registry import THRESHOLDS

        thr = {k: t.default for k, t in THRESHOLDS.items()}
        ok = np.ones(self.n, bool)
        if code == "acl101":
            t = self.design.transducer
            if t is None:
                return ok
            lo, hi = (self.get(f"transducer.band.{k}") for k in (0, 1)) if self.transducer_moves() else t.band
            for c in range(len(self.caps)):
                f = self.modes(c)[0]
                ok &= np.all(np.isnan(f) | ((f >= lo) & (f <= hi)), axis=1)
            return ok
        if code == "acl501":
            return self.marginal_features_ok(thr["print_margin"])
        if code == "acl502":
            fixed = {j.capsule for j in self.design.joints if j.kind == "fix"}
            limit = thr["substrate_clearance"]
            for c, cap in enumerate(self.caps):
                if cap.name in fixed:
                    continue
                low = self.capsule(c)["center"][:, 2] - self.half_height(c)
                ok &= ~(low < limit - 1e-9)
            return ok
        if code == "acl503":
            for c in range(len(self.caps)):
                ok &= np.all(self.capsule(c)["radii"] >= thr["orifice_min_radius"], axis=1)
            return ok
        if code == "acl504":
            for c in range(len(self.caps)):
                g = self.capsule(c)
                caps = interface_cap_volume(g["radii"]).sum(axis=1)
                ok &= ~((caps > 0) & (g["volume"] < thr["cap_volume_ratio"] * caps))
            return ok
        if code == "acl603":
            for i in range(1, len(self.design.requires) + 1):
                ok &= self.require(i)[1]
            return ok
        if code == "acl105":
            return self.linear_ok(thr["linear_amplitude"], int(thr["sweep_samples"]))
        if code == "acl201":
            return self.snap_in_ok(thr["snap_margin"])
        if code == "acl102":
            return self.gain_ok(thr["gain_ratio"])
        if code in ("acl401", "acl402"):
            return self.beam_lint(thr["strain_limit"], thr["eq1_tolerance"])[code]
        if code == "acl103":
            return self.crosstalk_ok(thr["bandwidth_overlap"])
        raise QuantityError("E-SWEEP-Q01", f"lint rule {code} is not batched")

    def lint_drives(self, p) -> list:
        """(step, frequencies, amplitudes) of each drive lint knows for the steps of program ``p``
        (acl.lint.context.Context._step_drives): a drive step's tones; each pinned tone of a
        follow/switch/hold alone at the step's limit (or the transducer's maximum); sweeps excluded."""
        out = []
        for i, st in enumerate(p.steps):
            if st.kind == "drive":
                out.append((st, tuple(t.frequency for t in st.drive.tones),
                            tuple(self.volt(f"programs.{p.name}.steps.{i}.drive.tones.{j}.amplitude", t.amplitude)
                                  for j, t in enumerate(st.drive.tones))))
            elif st.kind in ("follow", "switch", "hold") and st.tones:
                v = self.limit_volt(p, i, st)
                if v is not None:
                    out += [(st, (f,), (v,)) for f in st.tones]
        return out

    def snap_in_ok(self, margin: float) -> np.ndarray:
        """ACL201 (lint's default, without `mechanics`): no pair, outside the pairs a program's `hold`/`cross`
        governs and not both fixed, is closer than margin x Eq. 3's d_c, or attracted at rest by the net force,
        under a drive of the program while each capsule's thrust pushes it away from the other
        (lint.rules.forces.snap_in; acoustics.pair_table's dominant interfaces at the strongest tone)."""
        from acl.analysis.pairs import closing_component
        from acl.lint.rules.forces import managed_pairs

        ok = np.ones(self.n, bool)
        if len(self.caps) < 2:
            return ok
        lay = self.layout()
        names = [c.name for c in self.caps]
        fixed = {j.capsule for j in self.design.joints if j.kind == "fix"}
        rows = np.arange(self.n)
        for p in self.design.programs:
            crossing = managed_pairs(p)
            for _st, freqs, volts in self.lint_drives(p):
                if not freqs:
                    continue
                total, u, thr, att, pts = self.forces(lay["rest"], freqs, volts, parts=True)
                thrust_vec = np.einsum("bn,bnk,nc->bck", thr, -lay["normals"], lay["onehot"])
                mag = np.abs(u)                                                          # (N, T, n)
                for a, b in _pairs(self.design):
                    if tuple(sorted((a, b))) in crossing or (a in fixed and b in fixed):
                        continue
                    ca, cb = names.index(a), names.index(b)
                    ia, ib = np.flatnonzero(lay["body"] == ca), np.flatnonzero(lay["body"] == cb)
                    if not (ia.size and ib.size):
                        continue
                    sep = pts[:, ib][:, None, :, :] - pts[:, ia][:, :, None, :]
                    dd = np.linalg.norm(sep, axis=-1)
                    fa = np.einsum("bij,bijk->bk", att[:, ia][:, :, ib] / dd, sep)
                    line = lay["rest"][:, cb] - lay["rest"][:, ca]
                    dist = np.linalg.norm(line, axis=-1)
                    unit = line / np.where(dist > 0, dist, 1.0)[:, None]
                    attraction = np.einsum("bk,bk->b", fa, unit)
                    # dominant interfaces at the strongest tone (first maxima, as numpy's argmax)
                    t = np.argmax(mag[:, :, ia].max(axis=2) * mag[:, :, ib].max(axis=2), axis=1)
                    ja = ia[np.argmax(mag[rows, t][:, ia], axis=1)]
                    jb = ib[np.argmax(mag[rows, t][:, ib], axis=1)]
                    gap = np.linalg.norm(pts[rows, jb] - pts[rows, ja], axis=-1)
                    gamma2 = (np.einsum("bk,bk->b", thrust_vec[:, ca], -unit)
                              + np.einsum("bk,bk->b", thrust_vec[:, cb], unit))
                    alpha = attraction * gap**2
                    live = (alpha > 0) & (gamma2 > 0)
                    dc = np.where(live, critical_distance(np.where(live, alpha, 1.0), np.where(live, gamma2, 2.0) / 2),
                                  np.nan)             # paper Eq. 3, gamma2 = 2 gamma
                    pushed = (np.einsum("bk,bk->b", thrust_vec[:, ca], -unit) > 0) & \
                             (np.einsum("bk,bk->b", thrust_vec[:, cb], unit) > 0)
                    # or already pulled together at rest by the net force (inside analyze's d_c: where the net
                    # force changes sign)
                    closing = closing_component(total, lay["rest"], ca, cb)
                    ok &= ~(((gap < margin * dc) | ((attraction > 0) & (closing > 0))) & pushed)
        return ok

    def beam_lint(self, strain_limit: float, tolerance: float) -> dict:
        """ACL401 (clamp strain P (L + l) c / (E I) over the limit) and ACL402 (deflection beyond Eq. (1)'s
        validity) from each program's worst load on each beam carrying a capsule (lint.rules.beams.beam_loads:
        the first strongest drive of a step at rest, perpendicular to the beam; a `follow` path's reach)."""
        def build():
            from acl.lint.rules.beams import SAFE_RATIO, capsule_linked, path_extent
            from acl.physics.beams import eq1_deflection

            ok401, ok402 = np.ones(self.n, bool), np.ones(self.n, bool)
            lay = self.layout()
            names = [c.name for c in self.caps]
            for beam in self.design.beams:
                cap = next((j.capsule for j in self.design.joints if j.kind == "mount" and j.target == beam.name), None)
                if cap is None or capsule_linked(self, cap):     # linked: lint checks it only with mechanics
                    continue
                ci = names.index(cap)
                bm = self.beam_of(ci)
                if bm is None:
                    continue
                # lint.rules.beams.beam_loads: paper Eq. (1) with the declared modulus (no beam effects), the loads
                # from the force model with every effect
                L, l, EI, axis = bm["L"], bm["l"], bm["EI_declared"], bm["axis"]
                base = f"beams.{beam.name}.section"
                c = self.get(f"{base}.diameter") / 2 if beam.section.shape == "circle" else \
                    np.minimum(self.get(f"{base}.width"), self.get(f"{base}.thickness")) / 2
                for p in self.design.programs:
                    worst_p = np.full(self.n, np.nan)
                    worst_d = np.full(self.n, np.nan)
                    drives = {id(st): [] for st in p.steps}
                    for st, freqs, volts in self.lint_drives(p):
                        drives[id(st)].append((freqs, volts))
                    for st in p.steps:
                        if st.kind == "follow":
                            if st.capsule != cap:
                                continue
                            ext = path_extent(st)
                            if ext is None:
                                continue
                            P, defl = PB.eq1_force(np.full(self.n, ext), L, l, EI), np.full(self.n, ext)
                        elif st.kind == "hold" and st.mode == "cross" and cap in (st.a.split(".")[0], st.b.split(".")[0]):
                            continue
                        else:
                            if not drives[id(st)]:
                                continue
                            P = None
                            for freqs, volts in drives[id(st)]:       # the first strongest drive
                                F = self.forces(lay["rest"], freqs, volts)[:, ci]
                                load = np.linalg.norm(F - np.einsum("bk,bk->b", F, axis)[:, None] * axis, axis=-1)
                                P = load if P is None else np.where(load > P, load, P)
                            defl = eq1_deflection(P, L, l, EI)
                        better = np.isnan(worst_p) | (P > worst_p)
                        worst_p, worst_d = np.where(better, P, worst_p), np.where(better, defl, worst_d)
                    has = np.isfinite(worst_p)
                    strain = clamp_strain(worst_p, L, l, c, EI)
                    ok401 &= ~(has & (strain > strain_limit))
                    rigid = np.array([round(float(v), 2) for v in (l / L)]) if self.n else np.zeros(0)
                    ratio = np.ones(self.n)
                    for r in np.unique(rigid):
                        ratio[rigid == r] = eq1_limit_ratio(float(r), tolerance)
                    skip = (tolerance >= 0.05) & (worst_d < SAFE_RATIO * L)
                    ok402 &= ~(has & ~skip & (worst_d > ratio * L))
            return {"acl401": ok401, "acl402": ok402}
        return self.once(("beam_lint", strain_limit, tolerance), build)

    def gain_ok(self, ratio: float) -> np.ndarray:
        """ACL102: the transducer's gain at every in-band mode is at least ``ratio`` x its best gain over
        a 400-point grid of the band (lint.rules.acoustics.low_transducer_gain), per point's band and table."""
        ok = np.ones(self.n, bool)
        t = self.design.transducer
        if t is None:
            return ok
        moves = self.transducer_moves()
        if moves:
            lo, hi = self.get("transducer.band.0"), self.get("transducer.band.1")
            step = (hi - lo) / 399                            # np.linspace(lo, hi, 400), row by row, same bits
            grid = np.arange(400)[None, :] * step[:, None] + lo[:, None]
            grid[:, -1] = hi
            fs, gs = self.gain_table()
            best = pressure_per_volt_rows(grid, fs, gs).max(axis=1)
        else:
            lo, hi = t.band
            best = np.full(self.n, float(self.gain(np.linspace(lo, hi, 400)).max()))
        lo_, hi_ = np.broadcast_to(lo, (self.n,))[:, None], np.broadcast_to(hi, (self.n,))[:, None]
        for c in range(len(self.caps)):
            f = self.modes(c)[0]                                          # (N, P), NaN padded
            if f.shape[1] == 0:
                continue
            if moves:
                g = pressure_per_volt_rows(np.where(np.isfinite(f), f, 0.0), *self.gain_table())
            else:
                g = self.gain(np.where(np.isfinite(f), f, 0.0).ravel()).reshape(f.shape)
            inband = (lo_ <= f) & (f <= hi_)
            ok &= ~np.any(inband & (g < ratio * best[:, None]) & (best[:, None] > 0), axis=1)
        return ok

    def crosstalk_ok(self, k: float) -> np.ndarray:
        """ACL103: no two modes of capsules meant to be driven separately overlap within k x their mean
        half-bandwidth (lint.rules.acoustics.mode_crosstalk), modes and Q of each point."""
        from acl.lint.context import truss_group
        from acl.lint.rules.acoustics import separate_pairs

        class _Steps:                       # what separate_pairs reads: the design and its program steps
            design = self.design

            @staticmethod
            def steps():
                return ((p, st) for p in self.design.programs for st in p.steps)

            @staticmethod
            def tied(group):
                return truss_group(self.design, group)

        ok = np.ones(self.n, bool)
        idx = {c.name: i for i, c in enumerate(self.caps)}
        for (a, b) in separate_pairs(_Steps()):
            fa, qa = self.modes(idx[a])
            fb, qb = self.modes(idx[b])
            f1, q1 = fa[:, :, None], qa[:, :, None]
            f2, q2 = fb[:, None, :], qb[:, None, :]
            ok &= ~np.any(modes_overlap(f1, q1, f2, q2, k)[0], axis=(1, 2))
        return ok

    def half_height(self, c: int) -> np.ndarray:
        """Extent of capsule c's outer body below its centre (geometry.half_extent along -z)."""
        cap = self.caps[c]
        base = f"capsules.{cap.name}.cavity"
        cav = cap.cavity
        wall = self.get(f"{base}.wall")
        if cav.shape in ("cylinder", "prism"):
            ax = self.vec(f"{base}.axis")
            ca = np.abs(ax[:, 2]) / np.linalg.norm(ax, axis=-1)
            across = self.get(f"{base}.radius") if cav.shape == "cylinder" else self.get(f"{base}.side") / math.sqrt(3)
            return ca * self.get(f"{base}.height") / 2 + across * np.sqrt(np.maximum(0.0, 1 - ca * ca)) + wall
        return (3 * self.get(f"{base}.volume") / (4 * np.pi)) ** (1 / 3) + wall

    def marginal_features_ok(self, k: float) -> np.ndarray:
        """ACL501: no printed feature within k x the print resolution (lint.rules.fabrication._features)."""
        from acl.design.checks import PRINT_AXIAL, PRINT_LATERAL

        ok = np.ones(self.n, bool)

        def check(size, axial):
            res = PRINT_AXIAL if axial else PRINT_LATERAL
            return ~((res <= size) & (size < k * res))

        for cap in self.caps:
            ok &= check(self.get(f"capsules.{cap.name}.cavity.wall"), False)
            for o in cap.orifices:
                ok &= check(2 * self.get(f"capsules.{cap.name}.orifices.{o.name}.radius"), False)
        for b in self.design.beams:
            vertical = abs(b.axis[2]) > 0.7
            base = f"beams.{b.name}.section"
            if b.section.shape == "circle":
                ok &= check(self.get(f"{base}.diameter"), not vertical)
            else:
                ok &= check(self.get(f"{base}.width"), False) & check(self.get(f"{base}.thickness"), not vertical)
        for lt in self.design.latches:
            ok &= check(self.get(f"latches.{lt.name}.width"), False) & check(self.get(f"latches.{lt.name}.thickness"), True)
        return ok

    def linear_ok(self, limit: float, samples: int) -> np.ndarray:
        """ACL105: eps/R of every interface at every drive step and sampled sweep frequency within the limit (interfaces.interface_amplitudes)."""
        from acl.physics.forces import interface_centre_amplitude

        lay = self.layout()
        ok = np.ones(self.n, bool)
        for p in self.design.programs:
            for i, st in enumerate(p.steps):
                base = f"programs.{p.name}.steps.{i}."
                if st.kind == "drive":
                    drives = [(tuple(t.frequency for t in st.drive.tones),
                               tuple(self.volt(f"{base}drive.tones.{j}.amplitude", t.amplitude)
                                     for j, t in enumerate(st.drive.tones)))]
                elif st.kind == "sweep":
                    amp = self.volt(base + "amplitude", st.amplitude)
                    drives = [((float(f),), (amp,)) for f in np.linspace(st.f_start, st.f_stop, samples)]
                else:
                    continue
                for freqs, volts in drives:
                    f = np.array(freqs)
                    if f.size == 0:
                        continue
                    pts = lay["rest"][:, lay["body"]] + lay["offsets"]
                    u = PB.coupled_response(self.h0(tuple(f)), pts, lay["radii"], lay["body"], f[None, :],
                                            self.medium["density"], self.medium["sound_speed"], C.SUBSTRATE_REFLECTION)
                    pr = self.pressure(f, volts)
                    u = u * (pr[None, :, None] if pr.ndim == 1 else pr[:, :, None])
                    eps = interface_centre_amplitude(np.abs(u).sum(axis=1), lay["radii"])
                    ok &= np.all(eps / lay["radii"] <= limit, axis=1)
        return ok

    # -- dispatch ---------------------------------------------------------------------------------------
