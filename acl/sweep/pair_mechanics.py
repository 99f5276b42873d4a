"""Batched equilibria of a sweep's points: the snap-in of a pair on two beams (closure branch, fold), the plane
continuation, deflections at a drive and `require gap` over program steps (acl.sweep.mechanism for other mechanisms)."""
from __future__ import annotations

import numpy as np

from acl.design import model as M
from acl.physics.roots import golden_max, illinois_ascending
from acl.sweep.acoustic_state import PointAcoustics, _Rows, beam_force, beam_k0
from acl.sweep.columns import (
    SNAP_GOLDEN,
    SNAP_GRID,
    SPLIT_ITER,
    QuantityError,
    _closed_form,
    _elements,
    _ident,
    _mechanism,
    _uses_general,
)


class PairMechanics(PointAcoustics):
    """Snap-in, equilibria and deflections on top of the forces at rest."""

    def pair_setup(self):
        """Closure geometry of the pair on two beams: directions, projections, beam data."""
        def build():
            lay = self.layout()
            a, b = 0, 1
            ca, cb = self.caps[a], self.caps[b]
            # closest orifices at rest, as mechanics._closest_orifices (nominal choice)
            best = min(((np.linalg.norm(np.subtract(ob.center, oa.center)), ia, ib)
                        for ia, oa in enumerate(ca.orifices) for ib, ob in enumerate(cb.orifices)))
            ia = int(np.flatnonzero(lay["body"] == a)[best[1]])
            ib = int(np.flatnonzero(lay["body"] == b)[best[2]])
            pts = lay["rest"][:, lay["body"]] + lay["offsets"]
            line = pts[:, ib] - pts[:, ia]
            g0 = np.linalg.norm(line, axis=-1)
            nrm = line / g0[:, None]
            beams = [self.beam_of(a), self.beam_of(b)]
            dirs, cosines = [], []
            for k, (bm, sgn) in enumerate(zip(beams, (1.0, -1.0))):
                if bm is None:
                    dirs.append(np.zeros((self.n, 3)))
                    cosines.append(np.zeros(self.n))
                    continue
                ax = bm["axis"]
                e = sgn * (nrm - ax * np.einsum("bk,bk->b", nrm, ax)[:, None])
                en = np.linalg.norm(e, axis=-1)
                e = e / np.where(en > 0, en, 1.0)[:, None]
                dirs.append(e)
                cosines.append(np.einsum("bk,bk->b", e, sgn * nrm))
            return {"beams": beams, "dirs": dirs, "cos": cosines, "gap": g0, "n": nrm, "ia": ia, "ib": ib}
        return self.once("pair_setup", build)

    def pair_eval(self, xa, xb, freqs, volts):
        """Drive forces along each capsule's closing direction (fa, fb) and Eq. (1) beam loads (Pa, Pb) at deflections xa, xb."""
        ps = self.pair_setup()
        lay = self.layout()
        centres = lay["rest"].copy()
        for k, x in ((0, xa), (1, xb)):
            centres[:, k] = centres[:, k] + x[:, None] * ps["dirs"][k]
        F = self.forces(centres, freqs, volts)
        out = []
        for k, x in ((0, xa), (1, xb)):
            bm = ps["beams"][k]
            out.append(np.einsum("bk,bk->b", F[:, k], ps["dirs"][k]))
            out.append(beam_force(x, bm) if bm is not None else np.zeros_like(x))
        return out

    def pair_closure(self, s, t, freqs, volts):
        """V^2 balance at closure s and split t: (h residual, V^2 of beam a, V^2 of beam b, xa, xb)."""
        ps = self.pair_setup()
        xs = []
        for k, sgn in ((0, 1.0), (1, -1.0)):
            c = ps["cos"][k]
            xs.append(np.where(c > 0, (s + sgn * t) / (2 * np.where(c > 0, c, 1.0)), 0.0))
        if ps["beams"][0] is None:
            xs = [np.zeros_like(s), s / ps["cos"][1]]
        if ps["beams"][1] is None:
            xs = [s / ps["cos"][0], np.zeros_like(s)]
        fa, Pa, fb, Pb = self.pair_eval(xs[0], xs[1], freqs, volts)
        if ps["beams"][0] is None:
            return np.zeros_like(s), Pb / fb, Pb / fb, xs[0], xs[1]
        if ps["beams"][1] is None:
            return np.zeros_like(s), Pa / fa, Pa / fa, xs[0], xs[1]
        return Pa * fb - Pb * fa, Pa / fa, Pb / fb, xs[0], xs[1]

    def plane_setup(self):
        """Moving capsules (on beams) and an orthonormal basis (N, 3, 2) of each one's plane of motion (mechanics._perp_basis)."""
        def build():
            out = []
            for c in range(len(self.caps)):
                bm = self.beam_of(c)
                if bm is None:
                    continue
                ax = bm["axis"]
                trial = np.where((np.abs(ax[:, 0]) < 0.9)[:, None], np.array([1.0, 0, 0]), np.array([0, 1.0, 0]))
                e1 = trial - ax * np.einsum("bk,bk->b", trial, ax)[:, None]
                e1 /= np.linalg.norm(e1, axis=-1, keepdims=True)
                e2 = np.cross(ax, e1)
                out.append((c, bm, np.stack([e1, e2], axis=2)))
            return out
        return self.once("plane_setup", build)

    def plane_residual(self, q, lam, freqs, volts):
        """Equilibrium residual (N, m) of the in-plane displacements q (N, m): Eq. (1) restoring force - V^2 x drive force, per moving capsule."""
        lay = self.layout()
        moving = self.plane_setup()
        centres = lay["rest"].copy()
        for j, (c, _bm, basis) in enumerate(moving):
            centres[:, c] = centres[:, c] + np.einsum("bkj,bj->bk", basis, q[:, 2 * j:2 * j + 2])
        F = self.forces(centres, freqs, volts)
        res = np.empty_like(q)
        for j, (c, bm, basis) in enumerate(moving):
            qj = q[:, 2 * j:2 * j + 2]
            delta = np.linalg.norm(qj, axis=-1)
            P = beam_force(delta, bm)
            k0 = beam_k0(bm)
            ratio = np.where(delta > 1e-15 * bm["L"], P / np.where(delta > 0, delta, 1.0), k0)
            res[:, 2 * j:2 * j + 2] = ratio[:, None] * qj - lam[:, None] * np.einsum("bkj,bk->bj", basis, F[:, c])
        return res

    def plane_solve(self, q, lam, freqs, volts, iterations: int = 20, h: float = 1e-11):
        """Newton from q at drive scale lam (finite-difference Jacobian): (q, converged, smallest real eigenvalue of K_T)."""
        m = q.shape[1]
        conv = np.zeros(self.n, bool)
        lost = np.zeros(self.n, bool)            # Newton not contracting: no equilibrium near q (past a fold)
        mev = np.full(self.n, np.nan)
        prev = np.full(self.n, np.inf)
        for it in range(iterations):
            r = self.plane_residual(q, lam, freqs, volts)
            J = np.empty((self.n, m, m))
            for k in range(m):
                dq = q.copy()
                dq[:, k] += h
                J[:, :, k] = (self.plane_residual(dq, lam, freqs, volts) - r) / h
            try:
                step = np.linalg.solve(J, -r[..., None])[..., 0]
            except np.linalg.LinAlgError:
                step = np.full_like(q, np.nan)
            q = q + np.where((conv | lost)[:, None], 0.0, step)
            size = np.linalg.norm(step, axis=-1)
            small = size <= 1e-10 * np.linalg.norm(q, axis=-1) + 1e-18
            conv |= small & np.isfinite(step).all(axis=1) & ~lost
            if it >= 3:
                lost |= ~conv & ~(size < 0.5 * prev)
            prev = np.where(conv | lost, prev, size)
            mev = np.linalg.eigvals(np.where(np.isfinite(J), J, 0.0)).real.min(axis=1)
            if (conv | lost).all():
                break
        return q, conv & np.isfinite(q).all(axis=1), mev

    def plane_equilibrium(self, freqs, volts, steps: int = 8):
        """In-plane equilibrium at drive scale 1 by natural continuation in V^2 from rest: (q, ok); not ok after a lost or unstable step (snap-in)."""
        m = 2 * len(self.plane_setup())
        q = np.zeros((self.n, m))
        ok = np.ones(self.n, bool)
        for lam in np.linspace(0.0, 1.0, steps + 1)[1:]:
            q, conv, mev = self.plane_solve(q, np.full(self.n, lam), freqs, volts)
            ok &= conv & (mev > 0)
        return q, ok

    def plane_snap(self, freqs, volts, v_max: float, steps: int = 12, rtol: float = 1e-8) -> np.ndarray:
        """Snap-in voltage by continuation in V from 0 to v_max, Newton at each step, the step halved where the stable branch is lost (NaN: none below v_max)."""
        m = 2 * len(self.plane_setup())
        q = np.zeros((self.n, m))
        v = np.zeros(self.n)
        dv = np.full(self.n, v_max / steps)
        done = np.zeros(self.n, bool)
        snap = np.full(self.n, np.nan)
        failed = np.zeros(self.n, bool)          # once a step failed, steps only shrink (bisection of the fold)
        for _ in range(40 * steps):
            live = ~done
            if not live.any():
                break
            v_try = np.minimum(v + dv, v_max)
            qn, conv, mev = self.plane_solve(q, v_try * v_try, freqs, volts, iterations=12)
            good = conv & (mev > 0) & live
            q = np.where(good[:, None], qn, q)
            v = np.where(good, v_try, v)
            # grow after two successes in a row, halve after a failure (near the fold: a bisection)
            dv = np.where(good, np.where(failed, dv, np.minimum(dv * 1.5, v_max / steps)), np.where(live, dv / 2, dv))
            failed = live & ~good
            reached = good & (v >= v_max)
            folded = live & ~good & (dv < rtol * v_max)
            snap = np.where(folded, v, snap)
            done |= reached | folded
        return snap

    def pair_v2(self, s, t0, freqs, volts, slope=None):
        """V^2 on the equilibrium branch at closure s, the split t solved by secant from t0 (first step Newton with ``slope`` dh/dt when given).

        Returns (V^2, t, slope) with the last secant slope, to start the next closure.
        """
        ps = self.pair_setup()
        if ps["beams"][0] is None or ps["beams"][1] is None:
            _, va, _, _, _ = self.pair_closure(s, np.zeros_like(s), freqs, volts)
            return va, np.zeros_like(s), None
        h0, va, vb, _, _ = self.pair_closure(s, t0, freqs, volts)
        if slope is None:
            t1 = t0 + 1e-3 * s + 1e-15
        else:
            t1 = t0 - np.where(slope != 0, h0 / np.where(slope != 0, slope, 1.0), 0.0)
            t1 = np.clip(t1, t0 - 0.5 * s, t0 + 0.5 * s)
        h1, va1, vb1, _, _ = self.pair_closure(s, t1, freqs, volts)
        sl = slope
        for _ in range(SPLIT_ITER):
            den = h1 - h0
            ok = (den != 0) & (t1 != t0)
            sl = np.where(ok, den / np.where(t1 != t0, t1 - t0, 1.0), sl if sl is not None else 0.0)
            step = np.where(ok, -h1 / np.where(ok, sl, 1.0), 0.0)
            step = np.clip(step, -0.5 * s, 0.5 * s)
            if not np.any(np.abs(step) > 1e-10 * np.maximum(s, 1e-300)):      # NaN rows count as done
                break
            t0, h0 = t1, h1
            t1 = t1 + step
            h1, va1, vb1, _, _ = self.pair_closure(s, t1, freqs, volts)
        return 0.5 * (va1 + vb1), t1, sl

    def subset(self, rows: np.ndarray) -> PairMechanics:
        """An evaluator over the points ``rows`` only (the expensive branch searches skip the others)."""
        sub = _Rows(self.batch, rows)
        return type(self)(sub, self.at)

    def rest_checks(self, freqs: tuple, volts: tuple) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(closing, lateral, opening) at rest: the drive pulls both capsules towards each other; a lateral force the reduced branch ignores; it pushes both apart."""
        ps = self.pair_setup()
        lay = self.layout()
        F0 = self.forces(lay["rest"], freqs, volts)
        lateral = np.zeros(self.n, bool)
        for k in range(2):
            bm = ps["beams"][k]
            if bm is None:
                continue
            ax = bm["axis"]
            fperp = F0[:, k] - ax * np.einsum("bk,bk->b", F0[:, k], ax)[:, None]
            along = np.einsum("bk,bk->b", fperp, ps["dirs"][k])
            side = np.linalg.norm(fperp - along[:, None] * ps["dirs"][k], axis=-1)
            lateral |= side > 1e-6 * np.maximum(np.abs(along), 1e-300)
        # both moving capsules pulled towards each other: the closure parametrises the branch; both pushed
        # apart: the gap only grows (thrust against a Bjerknes pull that weakens with distance), no snap-in
        closing = np.ones(self.n, bool)
        opening = np.ones(self.n, bool)
        for k in range(2):
            if ps["beams"][k] is not None:
                along = np.einsum("bk,bk->b", F0[:, k], ps["dirs"][k])
                closing &= along > 0
                opening &= along <= 0
        return closing, lateral, opening

    def fold(self, freqs: tuple, volts: tuple) -> dict:
        """First maximum of V^2 along the closure (grid of SNAP_GRID, then golden section): V^2 and s there, and whether one was found."""
        gap = self.pair_setup()["gap"]
        grid = np.linspace(0.0, 1.0, SNAP_GRID + 1)[1:]
        v2 = np.empty((self.n, grid.size))
        ts = np.empty((self.n, grid.size))
        t = np.zeros(self.n)
        slope = None
        prev = None
        for k, frac in enumerate(grid):
            s = frac * gap * 0.999
            guess = t if prev is None else t * (frac / prev)
            v2[:, k], t, slope = self.pair_v2(s, guess, freqs, volts, slope)
            ts[:, k] = t
            prev = frac
        pos = np.where(np.isfinite(v2) & (v2 > 0), v2, -np.inf)
        falls = pos[:, :-1] > pos[:, 1:]
        has = falls.any(axis=1)
        k = np.where(has, np.argmax(falls, axis=1), grid.size - 1)
        rows = np.arange(self.n)
        lo = np.where(k > 0, grid[np.maximum(k - 1, 0)], 0.0) * gap * 0.999
        hi = grid[np.minimum(k + 1, grid.size - 1)] * gap * 0.999
        tguess = ts[rows, k]
        slopes = [slope]       # the first probe's slope is handed to every later one

        def v2(x, t):
            f, t_new, sl = self.pair_v2(x, t, freqs, volts, slopes[-1])
            if len(slopes) == 1:
                slopes.append(sl)
            return f, t_new

        fbest, sbest, _ = golden_max(v2, lo, hi, SNAP_GOLDEN, state=tguess)
        best = np.maximum(fbest, pos[rows, k])
        return {"v2": best, "s": sbest, "has": has}

    def pair_branch(self, freqs: tuple, volts: tuple) -> dict:
        """The fold (snap-in) of the pair's stable branch in the drive scale, searched only where the drive closes the pair."""
        def build():
            closing, lateral, opening = self.rest_checks(freqs, volts)
            rows = np.flatnonzero(closing & ~lateral)
            v2 = np.full(self.n, np.nan)
            s = np.full(self.n, np.nan)
            has = np.zeros(self.n, bool)
            if rows.size:
                sub = self if rows.size == self.n else self.subset(rows)
                with np.errstate(all="ignore"):
                    fo = sub.fold(freqs, volts)
                v2[rows] = np.where(fo["has"], fo["v2"], np.nan)
                s[rows], has[rows] = fo["s"], fo["has"]
            return {"v2_fold": v2, "s_fold": s, "lateral": lateral, "closing": closing, "opening": opening & ~lateral,
                    "has_fold": has}
        return self.once(("branch", freqs, volts), build)

    def snap_in(self, f: float) -> np.ndarray:
        """Snap-in voltage of a tone at ``f`` up to the transducer's maximum (NaN: none).

        Forces scale as V^2 x sat(V)^2 under a declared drive_saturation (acoustics.effect_pressure_factor): the
        fold is searched in X = V^2 sat(V)^2, increasing in V, with the unsaturated 1 V shape and the bound
        X(v_max), and V = sqrt(X / (1 - X / V_s^2)) there (the same equilibria, so the same fold as analyze's
        continuation in V with the saturating force model)."""
        vmax = self.design.transducer.max_voltage if self.design.transducer else 20.0
        if self.design.transducer is not None and self.moving("transducer.max_voltage"):
            vmax = self.get("transducer.max_voltage")          # each point's amplifier limit
        sat = self.coefficients("drive_saturation")
        shape = (1.0,)
        if sat is not None:
            inv = sat["inv_vsat2"]
            shape = (("shape", 1.0),)
            vmax = np.sqrt(vmax * vmax / (1.0 + inv * vmax * vmax))
        out = self._snap_in_shape(f, shape, vmax)
        if sat is not None:
            x = out * out
            out = np.sqrt(x / (1.0 - inv * x))
        return out

    def _snap_in_shape(self, f: float, shape: tuple, vmax) -> np.ndarray:
        if not _closed_form(self.design)[0]:                   # springs, latches, trusses, 3+ capsules
            def general():
                with np.errstate(all="ignore"):
                    return self.mechanism().snap_in((f,), shape, vmax)
            return self.once(("general_snap", f), general)
        br = self.pair_branch((f,), shape)
        v = np.sqrt(br["v2_fold"])
        out = np.where(v <= vmax, v, np.nan)
        # one pulled and one pushed, or a lateral force: both planes of motion, continuation in V
        rows = np.flatnonzero(~br["closing"] & ~br["opening"] | br["lateral"])
        if rows.size:
            with np.errstate(all="ignore"):
                out[rows] = self.subset(rows).plane_snap((f,), shape, vmax if np.ndim(vmax) == 0 else vmax[rows])
        return out

    def closing_equilibrium(self, freqs, volts, hi):
        """(xa, xb) where V^2(s) = 1 on the ascending branch, s in (0, hi): regula falsi (Illinois), V^2(0) = 0."""
        f_hi, t_hi, _ = self.pair_v2(hi, np.zeros(self.n), freqs, volts)

        def f(x, t_warm):
            v2, t, _ = self.pair_v2(x, t_warm, freqs, volts)
            return v2 - 1.0, t

        s, fs, t = illinois_ascending(f, np.zeros(self.n), hi, -np.ones(self.n), f_hi - 1.0, 30, 1e-12, 1e-13,
                                         state=t_hi)
        _, _, _, xa, xb = self.pair_closure(s, t, freqs, volts)
        bad = ~(np.abs(fs) <= 1e-9)                  # no root bracketed (or not converged): not an equilibrium
        return np.where(bad, np.nan, xa), np.where(bad, np.nan, xb)

    def pair_deflection(self, drive: M.Drive) -> dict:
        """Beam deflections of the pair at drive scale 1 on the stable branch from rest (mechanics.equilibrium): NaN after snap-in."""
        disp, ok = self.pair_equilibrium(tuple(t.frequency for t in drive.tones), tuple(t.amplitude for t in drive.tones))
        out = {"equilibrium_ok": ok}
        for c in range(len(self.caps)):
            bm = self.beam_of(c)
            if bm is not None:
                out[f"tip_deflection_{_ident(bm['name'])}_m"] = np.where(ok, np.linalg.norm(disp[:, c], axis=-1), np.nan)
        return out

    def mechanism(self):
        """The general batched mechanism (acl.sweep.mechanism) of these points."""
        from acl.sweep.mechanism import Mechanism, MechanismError

        def build():
            try:
                return Mechanism(self)
            except MechanismError as exc:
                raise QuantityError("E-SWEEP-Q02", f"the mechanism is not batched for these points: {exc}") from None
        return self.once("mechanism", build)

    def general_equilibrium(self, freqs: tuple, volts: tuple):
        """(displacement (N, C, 3), ok, deflections {element: (N,)}) of the general mechanism at a drive (mechanics.equilibrium)."""
        def build():
            me = self.mechanism()
            if not freqs:
                z, ok = np.zeros((self.n, me.m)), np.ones(self.n, bool)
            else:
                with np.errstate(all="ignore"):
                    z, ok = me.equilibrium(freqs, volts)
            return me.displacements(z), ok, me.deflections(z)
        return self.once(("general_eq", freqs, volts), build)

    def general_deflection(self, drive: M.Drive) -> dict:
        """Deflection columns of the general mechanism at ``drive`` (NaN after snap-in)."""
        _, ok, defl = self.general_equilibrium(tuple(t.frequency for t in drive.tones),
                                               tuple(t.amplitude for t in drive.tones))
        out = {"equilibrium_ok": ok}
        for name, kind in _elements(self.design):
            col = "tip_deflection" if kind == "beam" else "deflection"
            out[f"{col}_{_ident(name)}_m"] = np.where(ok, defl[name], np.nan)
        return out

    def pair_equilibrium(self, freqs: tuple, volts: tuple):
        """(displacement (N, C, 3), ok) of the pair's capsules at ``drive`` (mechanics.equilibrium from rest); not ok after snap-in.

        A pair the drive pulls together along its line: regula falsi on V^2(s) = 1 below the fold of
        the reduced branch; any other (pushed apart, one pushed and one pulled, a lateral force):
        natural continuation in V^2 with Newton on both beams' planes of motion.
        """
        return self.once(("pair_eq", freqs, volts), lambda: self._pair_equilibrium(freqs, volts))

    def _pair_equilibrium(self, freqs, volts):
        disp = np.zeros((self.n, len(self.caps), 3))
        if not freqs:
            return disp, np.ones(self.n, bool)
        br = self.pair_branch(freqs, volts)
        ps = self.pair_setup()
        closing, lateral = br["closing"], br["lateral"]
        ok = np.zeros(self.n, bool)
        reach = closing & ~lateral & ~(br["v2_fold"] <= 1.0)       # no fold below the drive
        rows = np.flatnonzero(reach)
        if rows.size:
            sub = self.subset(rows)
            hi = np.where(br["has_fold"][rows], br["s_fold"][rows], ps["gap"][rows] * 0.999)
            with np.errstate(all="ignore"):
                xa, xb = sub.closing_equilibrium(freqs, volts, hi)
            for k, x in ((0, xa), (1, xb)):
                disp[rows, k] = x[:, None] * ps["dirs"][k][rows]
            ok[rows] = np.isfinite(xa) & np.isfinite(xb)
        rows = np.flatnonzero(~closing | lateral)
        if rows.size:
            sub = self.subset(rows)
            with np.errstate(all="ignore"):
                q, good = sub.plane_equilibrium(freqs, volts)
            for j, (c, _bm, basis) in enumerate(sub.plane_setup()):
                disp[rows, c] = np.einsum("bkj,bj->bk", basis, q[:, 2 * j:2 * j + 2])
            ok[rows] = good
        return disp, ok

    def gap_over_steps(self, a: str, b: str) -> np.ndarray:
        """require gap: the smallest distance of orifices a, b over rest and the equilibrium of every program step, 0 after snap-in (report._require)."""
        lay = self.layout()
        (ca, oa), (cb, ob) = a.split("."), b.split(".")
        names = [c.name for c in self.caps]

        def point(cap, orf, disp):
            k = names.index(cap)
            o = [x.name for x in self.caps[k].orifices].index(orf)
            i = int(np.flatnonzero(lay["body"] == k)[o])
            return lay["rest"][:, k] + lay["offsets"][:, i] + disp[:, k]

        zero = np.zeros((self.n, len(self.caps), 3))
        gap = np.linalg.norm(point(cb, ob, zero) - point(ca, oa, zero), axis=-1)
        general = _uses_general(self.design) and not (_mechanism(self.design) == "beams" and len(self.caps) == 2)
        for _p, _i, _st, freqs, volts in self.step_drives():
            if general:
                disp, ok, _ = self.general_equilibrium(freqs, volts)
            else:
                disp, ok = self.pair_equilibrium(freqs, volts)
            g = np.linalg.norm(point(cb, ob, disp) - point(ca, oa, disp), axis=-1)
            gap = np.minimum(gap, np.where(ok, g, 0.0))
        return gap

    # -- latches ------------------------------------------------------------------------------------
