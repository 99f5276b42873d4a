"""The batched state of a sweep's points: capsule geometry, modes and Q, the layout, drives and transducer per
point, and the acoustic forces at rest (acl.physics.batch; the scalar code they equal is named at each method)."""
from __future__ import annotations

import math

import numpy as np

from acl.design import model as M
from acl.physics import batch as PB
from acl.physics import constants as C
from acl.physics.forces import jet_drag, thrust_magnitude
from acl.physics.ties import TIE_RTOL, first_max
from acl.physics.transducer import pressure_per_volt_rows
from acl.sweep.columns import _fkey, _ident, _pairs


def _nominal(design, path: str) -> float:
    from acl.sweep.perturb import field_value

    return field_value(design, path)


class _Rows:
    """A FieldBatch restricted to some rows (same design, same fields)."""

    def __init__(self, batch, rows):
        self.design = batch.design
        self.rows = rows
        self.n = int(rows.size)
        self.valid = np.asarray(batch.valid, bool)[rows]
        self.fields = batch.fields            # which fields vary (membership only; values through get)
        self._batch = batch

    def get(self, path: str) -> np.ndarray:
        return np.broadcast_to(np.asarray(self._batch.get(path), float), (self._batch.n,))[self.rows]


class PointAcoustics:
    """Lazily computed groups of columns over the points of a FieldBatch (capsules, drives, forces at rest)."""

    def __init__(self, batch, at: str | None):
        from acl.analysis.acoustics import _medium

        self.batch = batch
        self.design = batch.design
        self.n = int(batch.n)
        self.valid = np.asarray(batch.valid, bool)
        self.at = at
        self.cache: dict = {}
        med = _medium(self.design)
        self.heat_ratio = med.gas_heat_capacity_ratio
        if self.design.medium is None:
            self.medium = {k: np.full(self.n, getattr(med, k)) for k in
                           ("density", "viscosity", "sound_speed", "surface_tension", "ambient_pressure",
                            "polytropic_index", "gas_thermal_diffusivity")}
        else:
            self.medium = {k: self.get(f"medium.{k}") for k in
                           ("density", "viscosity", "sound_speed", "surface_tension", "ambient_pressure",
                            "polytropic_index", "gas_thermal_diffusivity")}
        self.caps = list(self.design.capsules)

    # -- inputs ---------------------------------------------------------------------------------
    def get(self, path: str) -> np.ndarray:
        """The field over the points, invalid points replaced by the nominal value (the physics stays finite)."""
        arr = np.asarray(self.batch.get(path), float)
        arr = np.broadcast_to(arr, (self.n,))
        if not self.valid.all():
            arr = np.where(self.valid, arr, _nominal(self.design, path))
        return arr

    def get_opt(self, path: str) -> np.ndarray:
        """A field that may be None in the design (NaN then)."""
        try:
            nominal = _nominal(self.design, path)
        except (TypeError, AttributeError):
            return np.full(self.n, np.nan)
        arr = np.broadcast_to(np.asarray(self.batch.get(path), float), (self.n,))
        return np.where(self.valid, arr, nominal) if not self.valid.all() else arr

    def vec(self, path: str) -> np.ndarray:
        return np.stack([self.get(f"{path}.{k}") for k in range(3)], axis=-1)

    def once(self, key, fn):
        if key not in self.cache:
            self.cache[key] = fn()
        return self.cache[key]

    # -- capsule geometry ---------------------------------------------------------------------------
    def capsule(self, c: int) -> dict:
        def build():
            cap = self.caps[c]
            base = f"capsules.{cap.name}"
            cav = cap.cavity
            vol = self.get(f"{base}.cavity.volume")
            if cav.shape == "cylinder" and cav.radius and cav.height:
                r, h = self.get(f"{base}.cavity.radius"), self.get(f"{base}.cavity.height")
                rth = 3 * vol / (2 * np.pi * r**2 + 2 * np.pi * r * h)
            elif cav.shape == "prism" and cav.side and cav.height:
                s, h = self.get(f"{base}.cavity.side"), self.get(f"{base}.cavity.height")
                rth = 3 * vol / (math.sqrt(3) / 2 * s**2 + 3 * s * h)
            else:
                rth = (3 * vol / (4 * np.pi)) ** (1 / 3)
            radii = np.stack([self.get(f"{base}.orifices.{o.name}.radius") for o in cap.orifices], axis=1) \
                if cap.orifices else np.zeros((self.n, 0))
            pts = np.stack([self.vec(f"{base}.orifices.{o.name}.center") for o in cap.orifices], axis=1) \
                if cap.orifices else np.zeros((self.n, 0, 3))
            nrm = np.stack([self.vec(f"{base}.orifices.{o.name}.normal") for o in cap.orifices], axis=1) \
                if cap.orifices else np.zeros((self.n, 0, 3))
            nrm = nrm / np.linalg.norm(nrm, axis=-1, keepdims=True)
            qf = self.get_opt(f"{base}.quality_factor") if cap.quality_factor is not None else None
            gam = self.get_opt(f"{base}.thrust_coefficient") if cap.thrust_coefficient is not None else None
            wall = self.get(f"{base}.cavity.wall")
            return {"volume": vol, "rth": rth, "radii": radii, "points": pts, "normals": nrm,
                    "center": self.vec(f"{base}.center"), "q_declared": qf, "gamma": gam,
                    "outer": (3 * vol / (4 * np.pi)) ** (1 / 3) + wall}
        return self.once(("capsule", c), build)

    def bare(self, c: int) -> tuple:
        """Bare modes (omega, Q with a declared quality_factor, orifice volume) of capsule c."""
        def build():
            g = self.capsule(c)
            m = self.medium
            if g["radii"].shape[1] == 0:
                z = np.zeros((self.n, 0))
                return z, z, np.zeros((self.n, 0, 0))
            return PB.capsule_modes(g["volume"], g["radii"], m["density"], m["surface_tension"],
                                    m["ambient_pressure"], m["polytropic_index"], m["viscosity"], m["sound_speed"],
                                    g["rth"], self.heat_ratio, m["gas_thermal_diffusivity"],
                                    quality_override=g["q_declared"])
        return self.once(("bare", c), build)

    def modes(self, c: int) -> tuple[np.ndarray, np.ndarray]:
        """Reported modes of capsule c alone (acoustics.capsule_modes): frequency (N, P) Hz and Q (N, P), NaN-padded."""
        def build():
            g = self.capsule(c)
            om, q, vol = self.bare(c)
            p = g["radii"].shape[1]
            if p == 0:
                return np.zeros((self.n, 0)), np.zeros((self.n, 0))
            if p == 1:                               # one interface: the secular equation, its lowest root
                w, _, cq = PB.lowest_single_interface_mode(vol[:, 0], om, om / q, g["points"][:, 0], g["radii"][:, 0],
                                                           self.medium["density"], self.medium["sound_speed"],
                                                           C.SUBSTRATE_REFLECTION)
                f = (w / (2 * np.pi))[:, None]
                qq = cq[:, None] if g["q_declared"] is None else g["q_declared"][:, None]
                return f, qq
            body = np.zeros(p, int)
            w, cvol, cq = PB.coupled_modes(vol, om, om / q, g["points"], g["radii"], body,
                                           self.medium["density"], self.medium["sound_speed"], C.SUBSTRATE_REFLECTION)
            picked = _fundamentals(cvol)                                    # (N, P) mode index, -1 padded
            rows = np.arange(self.n)[:, None]
            safe = np.maximum(picked, 0)
            f = np.where(picked >= 0, w[rows, safe] / (2 * np.pi), np.nan)
            qq = np.where(picked >= 0, cq[rows, safe], np.nan)
            if g["q_declared"] is not None:
                qq = np.where(picked >= 0, g["q_declared"][:, None], np.nan)
            return f, qq
        return self.once(("modes", c), build)

    # -- the acoustic force engine ------------------------------------------------------------------
    def layout(self) -> dict:
        def build():
            body, radii, pts, nrm, phis, oms, dmps = [], [], [], [], [], [], []
            for c in range(len(self.caps)):
                g = self.capsule(c)
                om, q, vol = self.bare(c)
                p = g["radii"].shape[1]
                body += [c] * p
                radii.append(g["radii"])
                pts.append(g["points"])
                nrm.append(g["normals"])
                phis.append(vol)
                oms.append(om)
                dmps.append(om / q)
            nint = len(body)
            mtot = sum(o.shape[1] for o in oms)
            phi = np.zeros((self.n, nint, mtot))
            i0 = m0 = 0
            for ph in phis:
                pi_, mi = ph.shape[1], ph.shape[2]
                phi[:, i0:i0 + pi_, m0:m0 + mi] = ph
                i0, m0 = i0 + pi_, m0 + mi
            centres = np.stack([self.capsule(c)["center"] for c in range(len(self.caps))], axis=1)
            pts = np.concatenate(pts, axis=1)
            body = np.asarray(body, int)
            return {"body": body, "radii": np.concatenate(radii, axis=1), "offsets": pts - centres[:, body],
                    "normals": np.concatenate(nrm, axis=1), "phi": phi,
                    "omega": np.concatenate(oms, axis=1), "damping": np.concatenate(dmps, axis=1),
                    "rest": centres, "onehot": (body[:, None] == np.arange(len(self.caps))[None]).astype(float),
                    "outer": np.stack([self.capsule(c)["outer"] for c in range(len(self.caps))], axis=1)}
        return self.once("layout", build)

    # -- drives: the programs' amplitudes and the transducer's values per point -----------------------
    def moving(self, path: str) -> bool:
        """Whether field ``path`` varies over the points."""
        return path in self.batch.fields

    def transducer_moves(self) -> bool:
        return self.design.transducer is not None and any(p.startswith("transducer.") for p in self.batch.fields)

    def gain(self, f) -> np.ndarray:
        """Transducer gain (Pa/V) at the tones ``f`` (T,): (T,) from the design's table, or (N, T) from each
        point's table when a swept parameter moves the transducer (paper Fig. S1, linear interpolation)."""
        from acl.analysis.acoustics import drive_gain

        if not self.transducer_moves():
            return drive_gain(self.design, f)[0]
        fs, gs = self.gain_table()
        return pressure_per_volt_rows(np.broadcast_to(np.asarray(f, float), (self.n, np.size(f))), fs, gs)

    def gain_rows(self, f: np.ndarray) -> np.ndarray:
        """Gain (Pa/V) at one frequency per point ``f`` (N,)."""
        from acl.analysis.acoustics import drive_gain

        if not self.transducer_moves():
            return drive_gain(self.design, f)[0]
        fs, gs = self.gain_table()
        return pressure_per_volt_rows(np.asarray(f, float)[:, None], fs, gs)[:, 0]

    def gain_table(self) -> tuple[np.ndarray, np.ndarray]:
        def build():
            t = self.design.transducer
            fs = np.stack([self.get(f"transducer.gain_frequencies.{k}") for k in range(len(t.gain_frequencies))], axis=1)
            gs = np.stack([self.get(f"transducer.gain_pa_per_v.{k}") for k in range(len(t.gain_pa_per_v))], axis=1)
            return fs, gs
        return self.once("gain_table", build)

    def volt(self, path: str, nominal: float, divisor: int = 1):
        """One tone's amplitude: the float ``nominal`` (computed as the scalar code does) when ``path`` does
        not vary, else a key (path, divisor) that :meth:`volts` reads per point (hashable: cache keys)."""
        return ("field", path, divisor) if self.moving(path) else nominal

    def volts(self, volts: tuple) -> np.ndarray:
        """Tone amplitudes (T,) of a drive whose amplitudes are floats, else (N, T) per point."""
        if all(isinstance(v, (int, float)) for v in volts):
            return np.asarray(volts, float)
        return np.stack([self._volt(v) for v in volts], axis=1) if volts else np.zeros((self.n, 0))

    def _volt(self, v) -> np.ndarray:
        if isinstance(v, (int, float)):
            return np.full(self.n, float(v))
        if v[0] == "field":
            return self.get(v[1]) / v[2] if v[2] != 1 else self.get(v[1]).copy()
        # ("max", elements): the largest amplitude applied at a frequency, 0 -> the reference (report._amplitude_at)
        from acl.analysis.report import DEFAULT_V

        best = np.zeros(self.n)
        for e in v[1]:
            best = np.maximum(best, self._volt(e))
        return np.where(best > 0, best, DEFAULT_V)

    def pressure(self, freqs, volts: tuple) -> np.ndarray:
        """Drive pressure amplitude (Pa) of each tone: (T,), or (N, T) when amplitudes or gains vary per point."""
        return self.volts(volts) * self.gain(np.asarray(freqs, float))

    def limit_volt(self, p, i: int, st):
        """The voltage limit of a follow/switch/hold step: its own `limit`, else the transducer's maximum
        (None: neither; report.step_drives then uses the reference voltage)."""
        if st.limits.max_voltage is not None:
            return self.volt(f"programs.{p.name}.steps.{i}.limits.max_voltage", st.limits.max_voltage)
        if self.design.transducer is not None:
            return self.volt("transducer.max_voltage", self.design.transducer.max_voltage)
        return None

    def step_drives(self) -> list:
        """(program, step index, step, frequencies, amplitudes) of every step with a definite drive
        (report.step_drives), the amplitudes per point where a swept parameter moves them."""
        def build():
            from acl.analysis.report import step_drives

            out = []
            for p, i, st, drive in step_drives(self.design):
                freqs = tuple(t.frequency for t in drive.tones)
                if st.kind == "drive":
                    volts = tuple(self.volt(f"programs.{p.name}.steps.{i}.drive.tones.{j}.amplitude", t.amplitude)
                                  for j, t in enumerate(drive.tones))
                else:
                    lim = self.limit_volt(p, i, st)
                    volts = tuple(t.amplitude if not isinstance(lim, tuple) else ("field", lim[1], len(st.tones))
                                  for t in drive.tones)
                out.append((p, i, st, freqs, volts))
            return out
        return self.once("step_drives", build)

    def amplitude_at(self, f: float):
        """The largest amplitude the programs apply at f (report._amplitude_at), per point when it moves."""
        from acl.analysis.report import _amplitude_at

        elems, moving = [], False
        for p in self.design.programs:
            for i, st in enumerate(p.steps):
                if st.kind == "drive":
                    for j, t in enumerate(st.drive.tones):
                        if t.frequency == f:
                            e = self.volt(f"programs.{p.name}.steps.{i}.drive.tones.{j}.amplitude", t.amplitude)
                            elems.append(e)
                            moving |= isinstance(e, tuple)
                elif st.kind in ("follow", "switch", "hold") and f in st.tones:
                    e = self.limit_volt(p, i, st)
                    if e is not None:
                        elems.append(e)
                        moving |= isinstance(e, tuple)
        return ("max", tuple(elems)) if moving else _amplitude_at(self.design, f)

    def thrust_scale(self) -> np.ndarray:
        """(N, C) declared thrust coefficient / the capsule's own thrust per V^2 at its first reported mode (acoustics._thrust_scale)."""
        def build():
            out = np.ones((self.n, len(self.caps)))
            for c in range(len(self.caps)):
                g = self.capsule(c)
                if g["gamma"] is None or g["radii"].shape[1] == 0:
                    continue
                om, q, vol = self.bare(c)
                f1 = self.modes(c)[0][:, 0]
                p = g["radii"].shape[1]
                body = np.zeros(p, int)
                h0 = PB.uncoupled_response(vol, om, om / q, body, f1[:, None])
                u = PB.coupled_response(h0, g["points"], g["radii"], body, f1[:, None], self.medium["density"],
                                        self.medium["sound_speed"], C.SUBSTRATE_REFLECTION)[:, 0]
                u = u * self.gain_rows(f1)[:, None]
                per = thrust_magnitude(u, g["radii"], 2 * np.pi * f1[:, None], self.medium["viscosity"][:, None],
                                       C.STREAMING_CONSTANT)
                total = np.linalg.norm((per[..., None] * -g["normals"]).sum(axis=1), axis=-1)
                out[:, c] = np.where(total > 0, g["gamma"] / np.where(total > 0, total, 1.0), 1.0)
            return out
        return self.once("thrust_scale", build)

    def h0(self, freqs: tuple) -> np.ndarray:
        lay = self.layout()
        return self.once(("h0", freqs), lambda: PB.uncoupled_response(
            lay["phi"], lay["omega"], lay["damping"], lay["body"], np.asarray(freqs, float)[None, :]))

    def forces(self, centres, freqs: tuple, volts, parts: bool = False):
        """Total acoustic force (N, C, 3) at capsule centres (N, C, 3) for tones (freqs, volts) (acoustics._Engine.forces)."""
        lay = self.layout()
        f = np.asarray(freqs, float)
        pressure = self.pressure(f, volts)                                # (T,) or (N, T) per point
        pts = centres[:, lay["body"]] + lay["offsets"]                    # (N, n, 3)
        if not parts and f.size == 1 and lay["body"].tolist() == [0, 1]:  # two one-orifice capsules, one tone
            h = self.h0(tuple(freqs))[:, 0]
            return PB.two_bubble_forces(np.stack([h[:, 0, 0], h[:, 1, 1]], axis=1), pts, lay["radii"], lay["normals"],
                                        centres, lay["outer"], self.thrust_scale(), 2 * np.pi * f[0], pressure[..., 0],
                                        self.medium["density"], self.medium["sound_speed"], self.medium["viscosity"],
                                        C.STREAMING_CONSTANT, C.SUBSTRATE_REFLECTION)
        u = PB.coupled_response(self.h0(tuple(freqs)), pts, lay["radii"], lay["body"], f[None, :],
                                self.medium["density"], self.medium["sound_speed"], C.SUBSTRATE_REFLECTION)
        u = u * (pressure[None, :, None] if pressure.ndim == 1 else pressure[:, :, None])   # (N, T, n)
        w = 2 * np.pi * f
        thr = thrust_magnitude(u, lay["radii"][:, None, :], w[None, :, None], self.medium["viscosity"][:, None, None],
                               C.STREAMING_CONSTANT).sum(axis=1) * self.thrust_scale()[:, lay["body"]]   # (N, n)
        f_thr = np.einsum("bn,bnk,nc->bck", thr, -lay["normals"], lay["onehot"])
        sep = pts[:, None, :, :] - pts[:, :, None, :]                     # p_j - p_i
        other = lay["body"][:, None] != lay["body"][None, :]
        d = np.where(other, np.linalg.norm(sep, axis=-1), 1.0)
        prod = np.einsum("t,bti,btj->bij", w**2, u, np.conj(u)).real
        att = self.medium["density"][:, None, None] * prod / (8 * np.pi * d**2) * other
        f_bj = np.einsum("bij,bijk,ic->bck", att / d, sep, lay["onehot"])
        x = centres[:, None, :, :] - pts[:, :, None, :]                    # (N, n, C, 3)
        dist = np.linalg.norm(x, axis=-1)
        cos = np.einsum("bnck,bnk->bnc", x, lay["normals"]) / dist
        mask = lay["body"][:, None] != np.arange(len(self.caps))[None, :]
        drag = jet_drag(thr[:, :, None], np.where(mask, dist, 1.0), cos, lay["outer"][:, None, :]) * mask
        f_dr = np.einsum("bnc,bnk->bck", drag, lay["normals"])
        total = f_thr + f_bj + f_dr
        if parts:
            return total, u, thr, att, pts
        return total

    # -- pairs at the program frequencies -------------------------------------------------------------
    def pair_quantities(self, f: float) -> dict:
        def build():
            lay = self.layout()
            v = self.amplitude_at(f)
            centres = lay["rest"]
            _, u, thr, att, pts = self.forces(centres, (f,), (v,), parts=True)
            thrust_vec = np.einsum("bn,bnk,nc->bck", thr, -lay["normals"], lay["onehot"])
            out = {}
            for a, b in _pairs(self.design):
                ia_, ib_ = self.caps.index(self.design.capsule(a)), self.caps.index(self.design.capsule(b))
                ia, ib = np.flatnonzero(lay["body"] == ia_), np.flatnonzero(lay["body"] == ib_)
                sep = pts[:, ib][:, None, :, :] - pts[:, ia][:, :, None, :]
                dd = np.linalg.norm(sep, axis=-1)
                fa = np.einsum("bij,bijk->bk", att[:, ia][:, :, ib] / dd, sep)
                line = centres[:, ib_] - centres[:, ia_]
                dist = np.linalg.norm(line, axis=-1)
                unit = line / np.where(dist > 0, dist, 1.0)[:, None]
                attraction = np.einsum("bk,bk->b", fa, unit)
                va, vb = u[:, 0, ia], u[:, 0, ib]
                rows = np.arange(self.n)
                ja, jb = first_max(np.abs(va), axis=1), first_max(np.abs(vb), axis=1)   # ties: acoustics.pair_table
                dphi = np.angle(va[rows, ja] * np.conj(vb[rows, jb]))
                gap = np.linalg.norm(pts[rows, ib[jb]] - pts[rows, ia[ja]], axis=-1)
                gamma2 = np.einsum("bk,bk->b", thrust_vec[:, ia_], -unit) + np.einsum("bk,bk->b", thrust_vec[:, ib_], unit)
                alpha = attraction * gap**2
                dc = np.where((alpha > 0) & (gamma2 > 0), np.sqrt(np.abs(alpha / np.where(gamma2 != 0, gamma2, 1.0))), np.nan)
                tag = f"{_ident(a)}_{_ident(b)}_{_fkey(f)}"
                out[f"force_{tag}_n"] = attraction
                out[f"attract_{tag}"] = attraction > 0
                out[f"phase_{tag}_deg"] = np.degrees(dphi)
                out[f"critical_distance_{tag}_m"] = dc
            return out
        return self.once(("pairs", f), build)

    # -- mechanics: a capsule on a beam, a pair on two beams ------------------------------------------
    def beam_of(self, c: int):
        j = self.design.mount_of(self.caps[c].name)
        if j is None or j.kind != "mount" or j.target_kind != "beam":
            return None
        beam = self.design.beam(j.target)
        base = f"beams.{beam.name}"
        sec = beam.section
        if sec.shape == "circle":
            i2 = np.pi * self.get(f"{base}.section.diameter") ** 4 / 64
        else:
            a_, b_ = self.get(f"{base}.section.width"), self.get(f"{base}.section.thickness")
            lo, hi = np.minimum(a_, b_), np.maximum(a_, b_)
            i2 = hi * lo**3 / 12
        axis = self.vec(f"{base}.axis")
        axis = axis / np.linalg.norm(axis, axis=-1, keepdims=True)
        return {"name": beam.name, "L": self.get(f"{base}.length"), "l": self.get(f"{base}.rigid_length"),
                "EI": self.get(f"{base}.youngs_modulus") * i2, "axis": axis}

    def single_deflection(self, drive: M.Drive) -> dict:
        """Load-point deflection of every beam carrying a lone capsule under ``drive`` (fixed point of Eq. (1) under the force at the displaced position)."""
        f = tuple(t.frequency for t in drive.tones)
        v = tuple(t.amplitude for t in drive.tones)
        lay = self.layout()
        out = {}
        (c,) = [i for i in range(len(self.caps)) if self.beam_of(i) is not None]
        bm = self.beam_of(c)
        ax = bm["axis"]
        proj = np.eye(3)[None] - ax[:, :, None] * ax[:, None, :]
        x = np.zeros((self.n, 3))
        delta = np.zeros(self.n)
        # one capsule on a beam along z moves parallel to the substrate: its force (own interfaces and
        # their images) does not depend on the deflection, so the first evaluation is the fixed point
        still = len(self.caps) == 1 and bool(np.all(np.abs(ax[:, 2]) == 1.0))
        for _ in range(1 if still else 30):
            centres = lay["rest"].copy()
            centres[:, c] = centres[:, c] + x
            F = np.einsum("bij,bj->bi", proj, self.forces(centres, f, v)[:, c])
            P = np.linalg.norm(F, axis=-1)
            new = PB_eq1_deflection(P, bm)
            x_new = F / np.where(P > 0, P, 1.0)[:, None] * new[:, None]
            done = np.all(np.abs(new - delta) <= 1e-13 * np.maximum(new, 1e-300))
            x, delta = x_new, new
            if done:
                break
        out[f"tip_deflection_{_ident(bm['name'])}_m"] = delta
        out["equilibrium_ok"] = np.isfinite(delta)
        return out


def PB_eq1_deflection(P, bm) -> np.ndarray:
    """Paper Eq. (1) load-point deflection with per-point beam geometry."""
    from acl.physics.beams import eq1_deflection

    return eq1_deflection(P, bm["L"], bm["l"], bm["EI"])


def _fundamentals(vol: np.ndarray) -> np.ndarray:
    """Each interface's own fundamental per point (acoustics._fundamentals), sorted, duplicates dropped: (N, P) mode indices, -1 padded.

    ``vol`` (N, P, K) outward volume of each interface in each coupled mode.
    """
    a = np.abs(vol)
    tot = a.sum(axis=1, keepdims=True)
    share = np.divide(a, tot, out=np.zeros_like(a), where=tot > 0)                    # (N, P, K)
    net = np.abs(vol.sum(axis=1)) / np.maximum(tot[:, 0], 1e-300)                       # (N, K)
    driven = net > 1e-3
    top = share >= share.max(axis=1, keepdims=True) * (1 - TIE_RTOL)                        # (N, P, K)
    cand = top & driven[:, None, :]
    has = cand.any(axis=2)
    first = np.argmax(cand, axis=2)                                                     # (N, P)
    # fallback: the largest-share driven mode (or any mode when none is driven)
    pool = np.where(driven.any(axis=1)[:, None, None], driven[:, None, :], True)
    alt = first_max(np.where(pool, share, -1.0), axis=2)
    picked = np.where(has, first, alt)
    picked = np.sort(picked, axis=1)
    dup = np.zeros_like(picked, bool)
    dup[:, 1:] = picked[:, 1:] == picked[:, :-1]
    picked = np.where(dup, np.iinfo(picked.dtype).max, picked)
    picked = np.sort(picked, axis=1)
    return np.where(picked == np.iinfo(picked.dtype).max, -1, picked)
