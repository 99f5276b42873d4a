"""What a rule sees: the resolved design, thresholds, the raw source, and cached analyses.

Analyses that several rules need (capsule modes, thrust over frequency, forces and pair tables
under each drive) come from the design's shared :class:`acl.analysis.cache.DesignAnalysis` (the
language server's hovers use the same object); the drives of each program step are built here.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache
from typing import Iterator

import numpy as np

from acl.design.model import Design, Drive, Program, Tone
from acl.diagnostics import Diagnostic, Severity, Span
from acl.lint.config import LintConfig
from acl.lint.registry import RULES
from acl.lint.source import SourceFile


class Unavailable(Exception):
    """The analysis a rule needs is not available; the rule reports nothing and says why (--verbose)."""


@dataclass
class Context:
    design: Design
    config: LintConfig
    source: SourceFile | None
    notes: list[str] = field(default_factory=list)
    _cache: dict = field(default_factory=dict)

    # -- bookkeeping ---------------------------------------------------------------------------
    def threshold(self, name: str) -> float:
        return self.config.threshold(name)

    def note(self, code: str, text: str) -> None:
        self.notes.append(f"{code}: {text}")

    def finding(self, code: str, message: str, span: Span | None, notes=(), hint: str | None = None,
                severity: Severity | None = None) -> Diagnostic:
        sev = severity or RULES[code].severity
        return Diagnostic(code, sev, message, span, hint, tuple(notes))

    def cached(self, key, compute):
        if key not in self._cache:
            self._cache[key] = compute()
        return self._cache[key]

    # -- acoustics (the design's shared analysis: acl.analysis.cache) -------------------------
    @property
    def analysis(self):
        """The design's :class:`acl.analysis.cache.DesignAnalysis` (shared with the language server)."""
        an = self._cache.get("analysis")
        if an is None:
            from acl.analysis.cache import analysis_for

            an = self._cache["analysis"] = analysis_for(self.design)
        return an

    def modes(self, capsule) -> list:
        return self.analysis.modes(capsule)

    def gain(self, frequencies) -> np.ndarray:
        from acl.analysis.acoustics import drive_gain

        return drive_gain(self.design, frequencies)[0]

    def band(self) -> tuple[float, float]:
        """The transducer band, or the span of every capsule's modes when none is declared."""
        t = self.design.transducer
        if t is not None:
            return t.band
        fs = self.mode_frequencies()
        return (float(fs.min()) / 2, float(fs.max()) * 2) if fs.size else (1e3, 1e6)

    def thrust_grid(self) -> tuple[np.ndarray, np.ndarray]:
        """(frequencies, thrust per V^2 of each capsule) on a grid fine around every mode; cached.

        The first call solves the coupled system at the grid and at every program frequency in one batch.
        """
        def compute():
            lo, hi = self.band()
            fm, q, _ = self.analysis.mode_table()
            parts = [np.geomspace(lo, hi, 200)]
            parts.extend(f * (1 + np.linspace(-2, 2, 41) / max(qq, 0.5)) for f, qq in zip(fm.tolist(), q.tolist()))
            f = np.unique(np.concatenate(parts))
            f = f[f > 0]
            self.analysis.prefetch(np.concatenate([f, self.program_frequencies()]))
            return f, self.analysis.thrust_per_v2(f)
        return self.cached("thrust_grid", compute)

    def program_frequencies(self) -> np.ndarray:
        """Every frequency a program step names or samples (its drives), for one batched solve."""
        fs = [t.frequency for _, st in self.steps() for d in self.step_drives(st) for t in d.tones]
        fs += [f for _, st in self.steps() for f in self.step_frequencies(st)]
        n = int(self.threshold("sweep_samples"))
        for _, st in self.steps():
            if st.kind == "sweep":          # ACL105 samples sweeps evenly
                fs.extend(np.linspace(st.f_start, st.f_stop, n).tolist())
        return np.unique(np.array(fs, float))

    def relative_thrust(self, frequencies) -> np.ndarray:
        """Thrust of each capsule at ``frequencies`` / its own peak thrust: shape (n_capsules, F)."""
        _, grid = self.thrust_grid()
        peak = self.cached("thrust_peak", lambda: grid.max(axis=1, keepdims=True))
        t = self.analysis.thrust_per_v2(frequencies)
        return np.divide(t, peak, out=np.zeros_like(t), where=peak > 0)

    # -- structure -----------------------------------------------------------------------------
    def carried(self, target: str) -> list[str]:
        """Capsules moving with the element ``target``: mounted on it, and rigidly tied to those by trusses."""
        return self.tied([j.capsule for j in self.design.joints if j.kind == "mount" and j.target == target])

    def tied(self, group: list[str]) -> list[str]:
        """``group`` and every capsule rigidly tied to one of them by trusses (`link ... with truss`)."""
        return truss_group(self.design, group)

    # -- programs ------------------------------------------------------------------------------
    def steps(self) -> Iterator[tuple[Program, object]]:
        for p in self.design.programs:
            for st in p.steps:
                yield p, st

    def max_voltage(self, step) -> float | None:
        lim = getattr(step, "limits", None)
        if lim is not None and lim.max_voltage is not None:
            return lim.max_voltage
        t = self.design.transducer
        return t.max_voltage if t is not None else None

    def mode_frequencies(self) -> np.ndarray:
        """Every capsule's mode frequencies (Hz), in capsule order; cached."""
        return self.analysis.mode_table()[0]

    def sweep_frequencies(self, f0: float, f1: float) -> np.ndarray:
        lo, hi = sorted((f0, f1))

        def compute():
            n = int(self.threshold("sweep_samples"))
            modes = self.mode_frequencies()
            return np.unique(np.concatenate([np.geomspace(lo, hi, max(n, 2)), modes[(modes >= lo) & (modes <= hi)]]))
        return self.cached(("sweep_frequencies", lo, hi), compute)

    def step_drives(self, step) -> list[Drive]:
        """:meth:`_step_drives`, cached per step (a sweep's drives are built once, not once per rule and beam)."""
        return self.cached(("step_drives", id(step)), lambda: self._step_drives(step))

    def step_forces(self, step) -> tuple[list[Drive], np.ndarray]:
        """The drives of ``step`` and the total acoustic force on every capsule at rest under each:
        (drives, array (D, C, 3) in ``design.capsules`` order); the forces of each drive are cached, the
        array is not (a design's steps x drives x capsules would not fit)."""
        drives = self.step_drives(step)
        forces = np.zeros((len(drives), len(self.design.capsules), 3))
        for k, drive in enumerate(drives):
            forces[k] = self.analysis.force_array(drive)
        return drives, forces

    def _step_drives(self, step) -> list[Drive]:
        """The drives a step applies, as the worst cases lint can know before compiling.

        drive: its tones; sweep: single tones sampled across it (with every mode inside);
        follow/switch/hold with pinned tones (``using``): each tone alone at the step's limit (or
        the transducer's maximum); unpinned goal steps: nothing (the compiler picks the drive).
        """
        kind = step.kind
        if kind == "drive":
            return [step.drive]
        if kind == "sweep":          # steps sweeping the same range at the same amplitude share the drives
            return self.cached(("sweep_drives", step.f_start, step.f_stop, step.amplitude), lambda: [
                Drive(tones=(Tone(frequency=float(f), amplitude=step.amplitude),))
                for f in self.sweep_frequencies(step.f_start, step.f_stop)])
        if kind in ("follow", "switch", "hold") and step.tones:
            v = self.max_voltage(step)
            if v is None:
                return []
            return [Drive(tones=(Tone(frequency=f, amplitude=v),)) for f in step.tones]
        return []

    def step_frequencies(self, step) -> list[float]:
        if step.kind == "drive":
            return [t.frequency for t in step.drive.tones]
        if step.kind == "sweep":
            return [step.f_start, step.f_stop]
        return list(getattr(step, "tones", ()))

    def forces(self, drive: Drive) -> dict:
        """Total acoustic force on each capsule at rest under ``drive`` (cached per drive)."""
        return self.analysis.forces(drive)

    def pair_table(self, drive: Drive):
        """Every capsule pair's Bjerknes interaction under ``drive`` as arrays (cached per drive):
        :class:`acl.analysis.acoustics.PairTable`."""
        return self.analysis.pair_table(drive)

    def pair_attraction(self, drive: Drive) -> np.ndarray:
        """The ``attraction`` column (P,) of :meth:`pair_table` alone (the same numbers)."""
        return self.analysis.pair_attraction(drive)

    def pair_forces(self, drive: Drive) -> list:
        tab = self.pair_table(drive)
        return [tab.row(k) for k in range(tab.a.size)]

    def thrust_array(self, drive: Drive) -> np.ndarray:
        """Streaming thrust vector (N) of every capsule at rest under ``drive``, (C, 3); cached per drive."""
        return self.analysis.thrust_array(drive)

    def net_force_array(self, drive: Drive) -> np.ndarray:
        """Total acoustic force (N) on every capsule at rest under ``drive`` (thrust, Bjerknes, jet drag), (C, 3)."""
        return self.analysis.net_force_array(drive)

    def fixed_pairs(self, tab) -> np.ndarray:
        """(P,) True where both capsules of a pair of ``tab`` are fixed (`fix` joints)."""
        def compute():
            is_fixed = self.analysis.fixed()
            return is_fixed[tab.a] & is_fixed[tab.b]
        return self.cached(("fixed_pairs", tab.a.size), compute)


@lru_cache(maxsize=4096)
def khz(f: float) -> str:
    """``f`` Hz as kHz text (cached: a large design's findings name the same few frequencies tens of thousands of times)."""
    return f"{f / 1e3:.4g} kHz"


def um(x: float) -> str:
    return f"{x * 1e6:.3g} um"


def truss_group(design, group) -> list[str]:
    """``group`` and every capsule rigidly tied to one of them by trusses (`link ... with truss`)."""
    group = list(group)
    names = {c.name for c in design.capsules}
    grew = True
    while grew:
        grew = False
        for j in design.joints:
            if j.kind == "link" and j.element_kind == "truss" and j.a in names and j.b in names:
                for x, y in ((j.a, j.b), (j.b, j.a)):
                    if x in group and y not in group:
                        group.append(y)
                        grew = True
    return group
