"""The batched state of a sweep's points: capsule geometry, modes and Q, the layout, drives and transducer per
point, and the acoustic forces at rest (acl.physics.batch; the scalar code they equal is named at each method)."""
from __future__ import annotations

import math

import numpy as np

from acl.design import model as M
from acl.physics import batch as PB
from acl.physics.coupling import uncoupled_response
from acl.physics import constants as C
from acl.physics.forces import bjerknes_from_rates, bjerknes_pair_sum, critical_distance, jet_drag, thrust_magnitude
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
        from acl.analysis.acoustics import medium_constants

        self.batch = batch
        self.design = batch.design
        self.n = int(batch.n)
        self.valid = np.asarray(batch.valid, bool)
        self.at = at
        self.cache: dict = {}
        med = medium_constants(self.design)
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

    # -- declared effects the batched evaluation models (acl.sweep.columns.BATCHED_EFFECTS) -----------
    def coefficients(self, name: str) -> dict | None:
        """{coefficient: (N,) array} of the declared effect ``name`` in internal SI coordinates, nulls filled in
        (acl.analysis.effects.coefficients per point: a swept coefficient varies); None when not declared."""
        from acl.analysis import effects as EF

        def build():
            nominal = EF.coefficients(self.design, name)
            if nominal is None:
                return None
            out = {k: np.full(self.n, float(v)) for k, v in nominal.items()}
            for key in self.design.effect(name).params:
                path = f"effects.{name}.params.{key}"
                if path not in self.batch.fields:
                    continue
                values = self.get(path)
                if (name, key) in EF.ALIASES:
                    key, conv = EF.ALIASES[(name, key)]
                    values = np.array([conv(float(v)) for v in values], float)
                out[key] = np.asarray(values, float)
            return out
        return self.once(("effect", name), build)

    def e_scale(self) -> np.ndarray | float:
        """A declared stiffness_scale's E factor per point (acl.analysis.mechanics._e_scale), 1.0 without one."""
        sc = self.coefficients("stiffness_scale")
        return 1.0 if sc is None else sc["e_scale"]

    def force_scale(self) -> np.ndarray:
        """(N, C) thrust scale of each capsule: a declared thrust coefficient's (:meth:`thrust_scale`) x a declared
        substrate_proximity's factor (acoustics._compute_engine)."""
        sub = self.substrate()
        return self.thrust_scale() if sub is None else self.thrust_scale() * sub

    def pair_law(self, two: bool = False):
        """(factor (N,), gap exponent (N,), gap reference (N,)) of a declared bjerknes_scale (acl.analysis.effects.bjerknes_shape
        per point: no shape, exponent 0, without a finite positive gap_ref); None without one.  ``two``: the pair
        of a two-capsule design, its factor times a declared substrate_proximity's sqrt(s_a s_b)."""
        bs = self.coefficients("bjerknes_scale")
        sub = self.substrate() if two else None
        if bs is None and sub is None:
            return None
        if bs is None:                      # two capsules: the substrate's sqrt(s_a s_b) on their pair
            return np.sqrt(sub[:, 0] * sub[:, 1]), np.zeros(self.n), np.ones(self.n)
        if sub is not None:
            bs = {**bs, "factor": np.sqrt(sub[:, 0] * sub[:, 1]) * bs["factor"]}
        n = bs.get("gap_exponent", np.zeros(self.n))
        ref = bs.get("gap_ref", np.full(self.n, np.nan))
        shaped = (n != 0) & np.isfinite(ref) & (ref > 0)
        return bs["factor"], np.where(shaped, n, 0.0), np.where(shaped, ref, 1.0)

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
        if v[0] == "shape":             # a drive shape scaled by V: no saturation at it (:meth:`pressure`)
            return np.full(self.n, float(v[1]))
        if v[0] == "field":
            return self.get(v[1]) / v[2] if v[2] != 1 else self.get(v[1]).copy()
        # ("max", elements): the largest amplitude applied at a frequency, 0 -> the reference (report.amplitude_at)
        from acl.analysis.report import DEFAULT_V

        best = np.zeros(self.n)
        for e in v[1]:
            best = np.maximum(best, self._volt(e))
        return np.where(best > 0, best, DEFAULT_V)

    def pressure(self, freqs, volts: tuple) -> np.ndarray:
        """Drive pressure amplitude (Pa) of each tone: (T,), or (N, T) when amplitudes, gains or declared pressure
        effects vary per point (acoustics._compute_engine: amplitude x gain x acoustics.effect_pressure_factor, a
        declared drive_saturation at the tones' total amplitude, except for a drive shape ("shape", V))."""
        f = np.asarray(freqs, float)
        vs = self.volts(volts)
        p = vs * self.gain(f)
        factor = self.pressure_factor(f)
        sat = self.coefficients("drive_saturation")
        if sat is not None and not any(isinstance(v, tuple) and v[0] == "shape" for v in volts):
            from acl.physics.effects import saturation

            # at the drive's total amplitude (acoustics._compute_engine); a drive shape (snap-in) is scaled later
            s = saturation(np.broadcast_to(vs.sum(axis=-1), (self.n,)), sat["inv_vsat2"])[:, None]
            factor = np.ones((self.n, f.size)) * s if factor is None else factor * s
        return p if factor is None else p * factor

    def pressure_factor(self, f: np.ndarray):
        """(N, T) factor of declared transducer_gain (gain, tilt) and transducer_resonance on the drive pressure
        at tones ``f`` (acl.analysis.acoustics.effect_pressure_factor without drive_saturation, which is not
        batched); None without them."""
        from acl.physics import effects as PE

        tg, tr = self.coefficients("transducer_gain"), self.coefficients("transducer_resonance")
        if tg is None and tr is None:
            return None
        out = np.ones((self.n, f.size))
        if tg is not None:
            out = out * tg["gain"][:, None]
            tilt = (tg["gain_slope"] != 0) & np.isfinite(tg["f_ref"])
            if tilt.any():
                ref = np.where(tilt, tg["f_ref"], 1.0)[:, None]
                out = out * np.where(tilt[:, None], PE.gain_tilt(f[None, :], ref, tg["gain_slope"][:, None]), 1.0)
        if tr is not None:
            res = (tr["inv_f_ratio"] != 0) & np.isfinite(tr["f_ref"])
            if res.any():
                ref = np.where(res, tr["f_ref"], 1.0)[:, None]
                out = out * np.where(res[:, None], PE.transducer_resonance(f[None, :], ref, tr["inv_f_ratio"][:, None],
                                                                           tr["gain_q"][:, None]), 1.0)
        return out

    def substrate(self):
        """(N, C) force factor of a declared substrate_proximity at each capsule's first orifice height at rest
        (acl.analysis.acoustics.substrate_factor; the capsule centre without an orifice); None without one."""
        from acl.physics import effects as PE

        sp = self.coefficients("substrate_proximity")
        if sp is None:
            return None

        def build():
            lay = self.layout()
            z = lay["rest"][:, :, 2].copy()
            for c in range(len(self.caps)):
                first = np.flatnonzero(lay["body"] == c)
                if first.size:
                    z[:, c] = lay["rest"][:, c, 2] + lay["offsets"][:, first[0], 2]
            h = sp["h_substrate"][:, None]
            return np.where(h > 0, PE.substrate_factor(z, np.where(h > 0, h, 1.0)), 1.0)
        return self.once("substrate", build)

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
        """The largest amplitude the programs apply at f (report.amplitude_at), per point when it moves."""
        from acl.analysis.report import amplitude_at

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
        return ("max", tuple(elems)) if moving else amplitude_at(self.design, f)

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
                h0 = uncoupled_response(vol, om, om / q, 2 * np.pi * f1[:, None], body)
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
        return self.once(("h0", freqs), lambda: uncoupled_response(
            lay["phi"], lay["omega"], lay["damping"], 2 * np.pi * np.asarray(freqs, float)[None, :], lay["body"]))

    def forces(self, centres, freqs: tuple, volts, parts: bool = False):
        """Total acoustic force (N, C, 3) at capsule centres (N, C, 3) for tones (freqs, volts) (acoustics._Engine.forces)."""
        lay = self.layout()
        f = np.asarray(freqs, float)
        pressure = self.pressure(f, volts)                                # (T,) or (N, T) per point
        pts = centres[:, lay["body"]] + lay["offsets"]                    # (N, n, 3)
        if not parts and f.size == 1 and lay["body"].tolist() == [0, 1]:  # two one-orifice capsules, one tone
            h = self.h0(tuple(freqs))[:, 0]
            return self.neighbour_drag(centres, PB.two_bubble_forces(np.stack([h[:, 0, 0], h[:, 1, 1]], axis=1), pts, lay["radii"], lay["normals"],
                                        centres, lay["outer"], self.force_scale(), 2 * np.pi * f[0], pressure[..., 0],
                                        self.medium["density"], self.medium["sound_speed"], self.medium["viscosity"],
                                        C.STREAMING_CONSTANT, C.SUBSTRATE_REFLECTION, pair_law=self.pair_law(two=True)))
        u = PB.coupled_response(self.h0(tuple(freqs)), pts, lay["radii"], lay["body"], f[None, :],
                                self.medium["density"], self.medium["sound_speed"], C.SUBSTRATE_REFLECTION)
        u = u * (pressure[None, :, None] if pressure.ndim == 1 else pressure[:, :, None])   # (N, T, n)
        w = 2 * np.pi * f
        thr = thrust_magnitude(u, lay["radii"][:, None, :], w[None, :, None], self.medium["viscosity"][:, None, None],
                               C.STREAMING_CONSTANT).sum(axis=1) * self.force_scale()[:, lay["body"]]   # (N, n)
        f_thr = np.einsum("bn,bnk,nc->bck", thr, -lay["normals"], lay["onehot"])
        other = lay["body"][:, None] != lay["body"][None, :]
        coef = bjerknes_from_rates(1.0, 1.0, self.medium["density"][:, None, None] * other)      # (N, n, n)
        sub = self.substrate()
        if sub is not None:                 # a declared substrate_proximity (acoustics._compute_engine)
            pair = np.sqrt(sub[:, :, None] * sub[:, None, :])[:, lay["body"]][:, :, lay["body"]]
            coef = coef * pair
        law = self.pair_law()
        shape = (0.0, 1.0)
        if law is not None:                 # a declared bjerknes_scale, per point (acoustics._compute_engine)
            coef = coef * law[0][:, None, None]
            shape = (law[1][:, None, None], law[2][:, None, None])
        bj, att = bjerknes_pair_sum(pts, u, w**2, coef, other, *shape)
        f_bj = np.einsum("bnk,nc->bck", bj, lay["onehot"])
        x = centres[:, None, :, :] - pts[:, :, None, :]                    # (N, n, C, 3)
        dist = np.linalg.norm(x, axis=-1)
        cos = np.einsum("bnck,bnk->bnc", x, lay["normals"]) / dist
        mask = lay["body"][:, None] != np.arange(len(self.caps))[None, :]
        drag = jet_drag(thr[:, :, None], np.where(mask, dist, 1.0), cos, lay["outer"][:, None, :]) * mask
        f_dr = np.einsum("bnc,bnk->bck", drag, lay["normals"])
        total = self.neighbour_drag(centres, f_thr + f_bj + f_dr)
        if parts:
            return total, u, thr, att, pts
        return total

    def neighbour_drag(self, centres, total):
        """A declared neighbour_drag on the forces (N, C, 3) of capsules with a neighbour, weakening with each one's
        displacement from rest (acl.analysis.acoustics._apply_neighbour_drag, :func:`acl.physics.effects.drag_load`;
        1 at rest)."""
        from acl.analysis.effects import neighbour_capsules
        from acl.physics.effects import drag_load

        nd = self.coefficients("neighbour_drag")
        if nd is None or not np.any(nd["inv_plateau"] > 0):
            return total
        near = np.array([c.name in neighbour_capsules(self.design) for c in self.caps], float)
        delta = np.linalg.norm(centres - self.layout()["rest"], axis=-1) * near
        inv = nd["inv_plateau"][:, None, None]
        return np.where(inv > 0, drag_load(total, delta[..., None], inv), total)

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
                live = (alpha > 0) & (gamma2 > 0)       # paper Eq. 3's d_c (acoustics.pair_table), gamma2 = 2 gamma
                dc = np.where(live, critical_distance(np.where(live, alpha, 1.0), np.where(live, gamma2, 2.0) / 2), np.nan)
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
        out = {"name": beam.name, "L": self.get(f"{base}.length"), "l": self.get(f"{base}.rigid_length"),
               "EI": self.get(f"{base}.youngs_modulus") * self.e_scale() * i2, "axis": axis, "law": None,
               "EI_declared": self.get(f"{base}.youngs_modulus") * i2}      # lint's ACL401/402 (without effects)
        law = self.beam_law()
        if law is not None:       # declared stiffness_gradient / large_deflection: effects.effective_beam_deflection
            out["EI"] = self.get(f"{base}.youngs_modulus") * i2
            out["law"] = law
        return out

    def beam_law(self):
        """(e_scale, gradient, elastica weight) per point of declared stiffness_gradient / large_deflection (with
        stiffness_scale: acl.analysis.mechanics._beam_effects), None without either (paper Eq. (1) with E x e_scale)."""
        gr, ld = self.coefficients("stiffness_gradient"), self.coefficients("large_deflection")
        if gr is None and ld is None:
            return None
        es = self.e_scale()
        return (np.broadcast_to(np.asarray(es, float), (self.n,)),
                gr["e_gradient"] if gr is not None else np.zeros(self.n),
                ld["elastica_weight"] if ld is not None else np.zeros(self.n))

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
    """Paper Eq. (1) load-point deflection with per-point beam geometry (and declared beam effects: :func:`beam_force`)."""
    from acl.physics.beams import eq1_deflection

    if bm.get("law") is not None:
        from acl.physics.effects import effective_beam_deflection

        return effective_beam_deflection(P, bm["L"], bm["l"], bm["EI"], *bm["law"])
    return eq1_deflection(P, bm["L"], bm["l"], bm["EI"])


def beam_force(delta, bm, rows=None) -> np.ndarray:
    """Load (N,) at load-point deflection ``delta`` (N,) of a beam ``bm`` (:meth:`PointAcoustics.beam_of`): paper
    Eq. (1) inverted (physics.batch.eq1_force), or with declared beam effects physics.batch.effective_beam_force
    (acl.analysis.mechanics._beam_law); ``rows`` selects the beam's rows when ``delta`` covers only some points."""
    if bm.get("law") is None:
        return PB.eq1_force(delta, bm["L"], bm["l"], bm["EI"])
    return PB.effective_beam_force(delta, bm["L"], bm["l"], bm["EI"], *bm["law"])[0]


def beam_k0(bm) -> np.ndarray:
    """Small-load stiffness (N,) of a beam: paper Eq. (1)'s, or 1e-30 / the effective deflection at 1e-30 N
    (acl.analysis.mechanics._beam_law)."""
    from acl.physics.beams import eq1_small_force_stiffness

    if bm.get("law") is None:
        return eq1_small_force_stiffness(bm["L"], bm["l"], bm["EI"])
    return 1e-30 / PB_eq1_deflection(np.full(np.shape(bm["L"]), 1e-30), bm)


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
