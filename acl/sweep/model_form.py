"""Model-form uncertainty of a sweep's points beyond the soft validity limits (issue 24; acl.physics.validity).

Past a soft limit the model still has a meaning, but its forces carry a relative uncertainty that grows with the
distance past the limit: the interface amplitude eps/R beyond 0.25 (:func:`acl.physics.validity.amplitude_model_form`
of the point's eps/R and Q, as `acl analyze`'s validity findings) and the pair distance below twice the sum of the
orifice radii (:func:`acl.physics.validity.monopole_model_form`).  The streaming Reynolds number has no such figure
(the paper's measurements keep the V^2 law past it: only a warning), so it adds nothing here.  A `sweep` step
(a frequency sweep) is not included: its worst frequency depends on each point's modes (analyze's
sweep_worst_amplitude); lint's ACL105 column checks it against the limit.

Per point:

* ``model_form_rel``: the largest relative force uncertainty over the program's drive steps (eps/R of every
  interface at the point's pressure, coupled response at rest) and the pairs at rest;
* ``model_form_uncertain``: a force-dependent ``require`` (margin, gap) whose verdict could flip within it: the
  value scaled by ``1 -+ model_form_rel`` crosses a bound (for a gap the whole value is scaled: conservative).

* ``model_form_pair_uncertain``: on a design whose pair (secondary Bjerknes) forces no ``bjerknes_scale``
  calibrates (acl.analysis.effects.first_principles_pairs), a force-dependent require whose verdict differs with
  the Bjerknes force at the 2.5 or the 97.5 % quantile of the first-principles pair-scale spread (the predictive
  log-Student-t of the 3 ratios of acl.physics.constants.PAIR_SCALE_ROWS: 0.051x .. 180x) from its verdict with the first-principles force; the verdict is taken as monotone in the scale
  between the two ends.  The scale is one unknown of the model, the same for every point (not a tolerance drawn per
  point), so it widens the interval instead of entering the yield; ``model_form_uncertain`` includes these points;
* ``model_form_pair_median_pass``: every margin and gap require holds with the Bjerknes force at the fitted median
  of the ratios (4.49x), the verdict a calibration would most likely find (the note counts it beside the first-principles yield).

The table (acl.sweep.table) widens the yield's interval by these points: the lower bound counts the uncertain
passes as failures, the upper bound the uncertain failures as passes.
"""
from __future__ import annotations

import numpy as np

from acl.physics import batch as PB
from acl.physics import constants as C
from acl.physics import validity as VA
from acl.sweep.checks import Checks

FORCE_REQUIRES = ("margin", "gap")
PAIR_QUANTILES = (0.025, 0.975)      # the ends of the first-principles pair-scale spread a verdict is checked at


class ModelForm(Checks):
    """The model-form columns on top of the latch margins, requires and lint rules."""

    def capsule_q(self) -> np.ndarray:
        """(N, C) the largest reported Q of each capsule (analyze's validity_at: max over its modes; 10 without one)."""
        qs = []
        for c in range(len(self.caps)):
            q = self.modes(c)[1]
            qs.append(np.nanmax(np.where(np.isfinite(q), q, -np.inf), axis=1) if q.shape[1] else np.full(self.n, 10.0))
        q = np.stack(qs, axis=1) if qs else np.zeros((self.n, 0))
        return np.where(np.isfinite(q), q, 10.0)

    def step_eps(self, freqs: tuple, volts: tuple) -> np.ndarray:
        """(N, I) eps/R of every interface under a drive at rest (interfaces.interface_amplitudes)."""
        from acl.physics.forces import interface_centre_amplitude

        lay = self.layout()
        f = np.asarray(freqs, float)
        pts = lay["rest"][:, lay["body"]] + lay["offsets"]
        u = PB.coupled_response(self.h0(tuple(f)), pts, lay["radii"], lay["body"], f[None, :],
                                self.medium["density"], self.medium["sound_speed"], C.SUBSTRATE_REFLECTION)
        pr = self.pressure(f, volts)
        u = u * (pr[None, :, None] if pr.ndim == 1 else pr[:, :, None])
        return interface_centre_amplitude(np.abs(u).sum(axis=1), lay["radii"]) / lay["radii"]

    def model_form(self) -> dict:
        def build():
            rel = np.zeros(self.n)
            if self.caps:
                lay = self.layout()
                q = self.capsule_q()[:, lay["body"]]                   # (N, I) the Q of each interface's capsule
                for _p, _i, _st, freqs, volts in self.step_drives():
                    if freqs:
                        x = self.step_eps(freqs, volts)
                        # past the hemisphere the model has no meaning: 1 (as analyze's validity_at)
                        r = np.where(x > VA.AMPLITUDE_MEANING.value, 1.0, VA.amplitude_model_form(x, q))
                        rel = np.maximum(rel, np.max(np.where(x > VA.AMPLITUDE.value, r, 0.0), axis=1, initial=0.0))
                rel = np.maximum(rel, self.monopole_rel())
            out = {"model_form_rel": rel}
            unc = np.zeros(self.n, bool)
            for i, r in enumerate(self.design.requires, 1):
                if r.kind not in FORCE_REQUIRES:
                    continue
                value, ok = self.once(("require", i), lambda i=i: self.require(i))
                lo_v, hi_v = value * (1 - rel), value * (1 + rel)
                flip = np.zeros(self.n, bool)
                if r.lower is not None:
                    b = self.get(f"requires.{i - 1}.lower")
                    flip |= np.where(ok, lo_v < b, hi_v >= b)
                if r.upper is not None:
                    b = self.get(f"requires.{i - 1}.upper")
                    flip |= np.where(ok, hi_v > b, lo_v <= b)
                unc |= flip & (rel > 0) & np.isfinite(value)
            out["model_form_uncertain"] = unc | self.pair_flip()
            return out
        return self.once("model_form", build)

    def pair_flip(self) -> np.ndarray:
        """(N,) a force-dependent require whose verdict differs at either end of the first-principles pair-scale
        spread (PAIR_QUANTILES) from its verdict with the first-principles force; all False where the design's
        pairs are calibrated (a declared bjerknes_scale) or no such require is declared."""
        return self.pair_scale_columns()["model_form_pair_uncertain"]

    def pair_scale_columns(self) -> dict:
        """``model_form_pair_uncertain`` (:meth:`pair_flip`) and ``model_form_pair_median_pass``: every margin and gap
        require holds with the Bjerknes force at the spread's median (4.49x), as analyze's N-PAIR-SCALE snap-in."""
        def build():
            from dataclasses import replace

            from acl.analysis.effects import first_principles_pairs, with_pair_scale

            force = [i for i, r in enumerate(self.design.requires, 1) if r.kind in FORCE_REQUIRES]
            nominal = {i: np.asarray(self.once(("require", i), lambda i=i: self.require(i))[1], bool) for i in force}
            flip = np.zeros(self.n, bool)
            ok_median = np.ones(self.n, bool)
            if force and first_principles_pairs(self.design):
                for p in (*PAIR_QUANTILES, 0.5):
                    d = with_pair_scale(self.design, C.pair_scale_quantile(p) if p != 0.5 else C.FIRST_PRINCIPLES_PAIR_SCALE_MEDIAN)
                    ev = type(self)(replace(self.batch, design=d), self.at)
                    for i in force:
                        ok_p = np.asarray(ev.require(i)[1], bool)
                        if p == 0.5:
                            ok_median &= ok_p
                        else:
                            flip |= nominal[i] != ok_p
            else:
                for i in force:
                    ok_median &= nominal[i]
            return {"model_form_pair_uncertain": flip & self.valid, "model_form_pair_median_pass": ok_median & self.valid}
        return self.once("pair_scale", build)

    def monopole_rel(self) -> np.ndarray:
        """((R_a + R_b)/d)^2 of the closest interfaces of every pair at rest below the monopole limit, else 0
        (report._monopole: the sum of each capsule's largest orifice radius)."""
        lay = self.layout()
        pts = lay["rest"][:, lay["body"]] + lay["offsets"]                 # (N, I, 3)
        body = lay["body"]
        rel = np.zeros(self.n)
        for a in range(len(self.caps)):
            for b in range(a + 1, len(self.caps)):
                ia, ib = np.flatnonzero(body == a), np.flatnonzero(body == b)
                if not ia.size or not ib.size:
                    continue
                d = np.linalg.norm(pts[:, ia, None, :] - pts[:, None, ib, :], axis=-1).min(axis=(1, 2))
                rsum = lay["radii"][:, ia].max(axis=1) + lay["radii"][:, ib].max(axis=1)
                below = d / rsum < VA.MONOPOLE_DISTANCE.value
                rel = np.maximum(rel, np.where(below, VA.monopole_model_form(d, rsum), 0.0))
        return rel
