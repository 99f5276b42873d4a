"""Typed results of the Python API (:func:`acl.analyze`, :func:`acl.compile`, :func:`acl.lint`,
:func:`acl.fit`) with notebook display (``_repr_html_``: a compact table) and ``.plot()``.

Each result holds the same data as the command's JSON output (``as_dict()`` returns it, documented
in docs/analyze.md, docs/schedule.md, docs/rules.md, docs/fit.md) plus typed views of the main
rows.  ``.plot(ax=None)`` draws on the given matplotlib Axes, or on a new
:class:`matplotlib.figure.Figure` (object-oriented API, never pyplot), so the caller's backend is
never changed; it returns the Axes.  matplotlib is imported only when a plot is drawn.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any


# ------------------------------------------------------------------------------------------------
# Helpers
# ------------------------------------------------------------------------------------------------

from acl._display import html_table, new_axes, shown  # noqa: E402,F401  (shared with the sweep tables)


def _khz(hz: float | None) -> str:
    return "-" if hz is None else f"{hz / 1e3:.1f}"


def _num(v, fmt: str, scale: float = 1.0) -> str:
    return "-" if v is None else fmt.format(v * scale)


# ------------------------------------------------------------------------------------------------
# Design (acl.load / acl.loads): display helpers used by acl.design.model.Design
# ------------------------------------------------------------------------------------------------

def design_html(design) -> str:
    rows = []
    for c in design.capsules:
        radii = ", ".join(f"{o.name} {o.radius * 1e6:g} um" for o in c.orifices)
        rows.append(["capsule", c.name, f"V = {c.cavity.volume * 1e18:.4g} um^3; orifices {radii}"])
    for b in design.beams:
        rows.append(["beam", b.name, f"L = {b.length * 1e6:g} um, {b.material}, E = {b.youngs_modulus / 1e6:g} MPa"])
    for lt in design.latches:
        rows.append(["latch", lt.name, f"state {lt.state}"])
    for s in design.springs:
        rows.append(["spring", s.name, f"k = {s.stiffness:.3g} N/m"])
    for p in design.programs:
        rows.append(["program", p.name, f"{len(p.steps)} steps"])
    return html_table(f"Design {design.file}: {design.summary()}", ["kind", "name", "summary"], rows)


def plot_design(design, ax=None):
    """Top view (x-y, um): beams from clamp to tip, capsules at their centres, labelled."""
    ax = new_axes(ax)
    for b in design.beams:
        ax.plot([b.clamp[0] * 1e6, b.tip[0] * 1e6], [b.clamp[1] * 1e6, b.tip[1] * 1e6], "-", color="0.4", lw=2)
        ax.plot([b.clamp[0] * 1e6], [b.clamp[1] * 1e6], "s", color="0.2", ms=5)
    for c in design.capsules:
        ax.plot([c.center[0] * 1e6], [c.center[1] * 1e6], "o", ms=10, alpha=0.7)
        ax.annotate(c.name, (c.center[0] * 1e6, c.center[1] * 1e6), textcoords="offset points", xytext=(6, 6))
    ax.set_xlabel("x (um)")
    ax.set_ylabel("y (um)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_title(f"{design.file}: top view")
    return ax


# ------------------------------------------------------------------------------------------------
# acl.analyze
# ------------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Mode:
    """One predicted capsule mode (as `acl analyze`)."""

    frequency_hz: float          #: natural frequency (Hz)
    q: float                     #: quality factor (declared or predicted)
    q_declared: bool             #: True when the design declares Q
    dominant_orifice: str        #: orifice whose interface moves most
    share: float                 #: that interface's share of the volume oscillation (0..1)
    q_predicted: float | None = None   #: the model's Q when ``q`` is declared (None in older reports)


@dataclass(frozen=True)
class CapsuleModes:
    """A capsule's predicted modes, ascending in frequency."""

    name: str                    #: capsule name
    file: str                    #: file of its declaration
    line: int                    #: line of its declaration
    volume_m3: float             #: gas volume (m^3)
    modes: tuple[Mode, ...]      #: one per orifice, ascending in frequency


@dataclass
class Analysis:
    """What `acl analyze --output-format json` prints, typed.  Fields (docs/analyze.md):

    ``capsules`` (modes per capsule), ``frequencies_hz`` (the program frequencies),
    ``selectivity`` (relative response of each capsule at each frequency, crosstalk flagged),
    ``pairs`` (Bjerknes forces, critical distances, snap-in voltages), ``latches`` (margins per
    program step), ``equilibrium`` (at ``at``, or None), ``requires`` (each `require` evaluated),
    ``notes`` (defaults the model assumed).
    """

    file: str                    #: the design file
    capsules: list[CapsuleModes]     #: predicted modes of each capsule
    frequencies_hz: list[float]  #: every frequency a program uses (Hz)
    selectivity: list[dict]      #: {frequency_hz, capsule, relative_response, target, crosstalk}
    pairs: list[dict]            #: {a, b, frequency_hz, voltage_v, force_n, attract, ..., snap_in_voltage_v}
    latches: list[dict]          #: {name, bistable, switching_force_n, margins: [...]}
    equilibrium: dict | None     #: the equilibrium under ``at`` (None without it)
    requires: list[dict]         #: {text, value, unit, ok, file, line} per `require`
    notes: list[str]             #: defaults and effects the model used
    coupled_modes: list[dict] = field(default_factory=list)   #: all bubbles as one system: f, Q, shares, phases_deg
    drives: list[dict] = field(default_factory=list)          #: linear-regime check (eps/R) of each drive
    _raw: dict = field(repr=False, default_factory=dict)

    @classmethod
    def from_report(cls, rep) -> "Analysis":
        d = rep.as_dict()
        caps = [CapsuleModes(c["name"], c["file"], c["line"], c["volume_m3"],
                             tuple(Mode(m["frequency_hz"], m["q"], m["q_declared"], m["dominant_orifice"], m["share"],
                                        m.get("q_predicted")) for m in c["modes"])) for c in d["capsules"]]
        return cls(d["file"], caps, list(d["frequencies_hz"]), d["selectivity"], d["pairs"], d["latches"],
                   d["equilibrium"], d["requires"], d["notes"], list(d.get("coupled_modes") or []),
                   list(d.get("drives") or []), d)

    @property
    def requires_ok(self) -> bool:
        """True when every `require` of the design holds."""
        return all(r["ok"] for r in self.requires)

    def resonance(self, capsule: str) -> float:
        """First natural frequency (Hz) of ``capsule``.

        >>> import acl
        >>> a = acl.analyze("examples/fig1f_selective_beams.acl", snap_in=False)
        >>> abs(a.resonance("high") / 171.8e3 - 1) < 0.03   # paper Table S1, design 3: 171.8 kHz (3 %)
        True
        """
        for c in self.capsules:
            if c.name == capsule:
                return c.modes[0].frequency_hz
        raise KeyError(f"no capsule named {capsule!r}")

    def as_dict(self) -> dict:
        """The JSON object of `acl analyze --output-format json`.

        >>> import acl
        >>> d = acl.analyze("examples/fig1f_selective_beams.acl", snap_in=False).as_dict()
        >>> d["capsules"][0]["name"], d["frequencies_hz"]
        ('low', [85000.0, 170000.0])
        """
        return self._raw

    def _repr_html_(self) -> str:
        rows = [[c.name, i + 1, _khz(m.frequency_hz), f"{m.q:.1f}", f"{m.dominant_orifice} ({m.share:.0%})"]
                for c in self.capsules for i, m in enumerate(c.modes)]
        out = html_table(f"Capsule modes ({self.file})", ["capsule", "mode", "f (kHz)", "Q", "dominant orifice"], rows)
        if self.selectivity:
            out += html_table("Selectivity (response relative to each capsule's peak)",
                              ["f (kHz)", "capsule", "response", "target", "crosstalk"],
                              [[_khz(r["frequency_hz"]), r["capsule"], f"{r['relative_response']:.3f}",
                                "yes" if r.get("target") else "", "CROSSTALK" if r.get("crosstalk") else ""]
                               for r in self.selectivity])
        if self.pairs:
            out += html_table("Pairs (secondary Bjerknes force)",
                              ["pair", "f (kHz)", "V", "force (N)", "", "critical distance (um)", "gap (um)", "snap-in (V)"],
                              [[f"{p['a']}-{p['b']}", _khz(p.get("frequency_hz")), _num(p.get("voltage_v"), "{:g}"),
                                _num(p.get("force_n"), "{:.3g}"), "attract" if p.get("attract") else "repel",
                                _num(p.get("critical_distance_m"), "{:.1f}", 1e6), _num(p.get("gap_m"), "{:.1f}", 1e6),
                                _num(p.get("snap_in_voltage_v"), "{:.3g}")] for p in self.pairs])
        eq = self.equilibrium
        if eq:
            rows = [[f"capsule {c['name']}", "displacement (um)", ", ".join(f"{v * 1e6:.3g}" for v in c["displacement_m"])]
                    for c in eq.get("capsules", [])]
            rows += [[f"beam {k}", "tip deflection (um)", f"{v * 1e6:.3g}"] for k, v in (eq.get("deflections_m") or {}).items()]
            rows += [[f"gap {g['a']}-{g['b']}", "gap (um)", f"{g['gap_m'] * 1e6:.3g}"] for g in eq.get("gaps", [])]
            note = "; ".join(eq.get("warnings") or [])
            out += html_table(f"Equilibrium at {eq.get('drive', '')}: {eq.get('status', '')}"
                              + ("" if eq.get("stable", True) else " (unstable)"), ["", "quantity", "value"], rows, note)
        if self.requires:
            out += html_table("Requirements", ["requirement", "ok"], [[r["text"], "ok" if r["ok"] else "FAILED"]
                                                                    for r in self.requires])
        return out

    def plot(self, ax=None):
        """Each capsule's modes as stems (frequency vs Q); program frequencies as dashed lines.

        >>> import acl
        >>> ax = acl.analyze("examples/fig1f_selective_beams.acl", snap_in=False).plot()
        >>> ax.get_xlabel()
        'frequency (kHz)'
        """
        ax = new_axes(ax)
        for c in self.capsules:
            f = [m.frequency_hz / 1e3 for m in c.modes]
            q = [m.q for m in c.modes]
            ax.vlines(f, 0, q, lw=2, alpha=0.8)
            ax.plot(f, q, "o", label=c.name)
        for f in self.frequencies_hz:
            ax.axvline(f / 1e3, ls="--", color="0.5", lw=1)
        ax.set_xlabel("frequency (kHz)")
        ax.set_ylabel("Q")
        ax.set_title("predicted modes (dashed: program frequencies)")
        if self.capsules:
            ax.legend(fontsize="small")
        return ax


# ------------------------------------------------------------------------------------------------
# acl.lint
# ------------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Finding:
    """One lint finding or check diagnostic (as `acl lint --output-format json`)."""

    code: str                    #: rule code (ACLnnn) or check code (Ennn/Wnnn)
    name: str                    #: rule name, e.g. unused-declaration
    severity: str                #: error | warning | info
    message: str
    file: str | None
    line: int | None
    column: int | None
    hint: str | None


@dataclass
class LintResult:
    """The findings of :func:`acl.lint` for one file, sorted by location."""

    path: str                    #: the linted file
    findings: list[Finding]      #: findings and check diagnostics, sorted by location
    notes: list[str]             #: rules that could not run, and why
    _raw: dict = field(repr=False, default_factory=dict)

    @property
    def ok(self) -> bool:
        """True when there is no error (warnings allowed), as `acl lint` exits 0."""
        return not any(f.severity == "error" for f in self.findings)

    def codes(self) -> list[str]:
        """The codes found, in order.

        >>> import acl
        >>> acl.lint("examples/fig1f_selective_beams.acl").codes()
        []
        """
        return [f.code for f in self.findings]

    def as_dict(self) -> dict:
        """The JSON document of `acl lint --output-format json PATH`.

        >>> import acl
        >>> acl.lint("examples/fig1f_selective_beams.acl").as_dict()["summary"]
        {'findings': 0, 'errors': 0}
        """
        return self._raw

    def _repr_html_(self) -> str:
        rows = [[f.code, f.name, f.severity, f"{f.line}:{f.column}" if f.line else "", f.message] for f in self.findings]
        return html_table(f"acl lint {self.path}: {len(self.findings)} finding(s)",
                          ["code", "rule", "severity", "at", "message"], rows)

    def plot(self, ax=None):
        """Number of findings per code (horizontal bars).

        >>> import acl
        >>> acl.lint("examples/fig1f_selective_beams.acl").plot().get_xlabel()
        'findings'
        """
        ax = new_axes(ax)
        counts: dict[str, int] = {}
        for f in self.findings:
            counts[f.code] = counts.get(f.code, 0) + 1
        codes = sorted(counts)
        ax.barh(codes, [counts[c] for c in codes])
        if not codes:
            ax.text(0.5, 0.5, "no findings", ha="center", va="center", transform=ax.transAxes)
            ax.set_yticks([])                   # no code to list: no -0.04 .. 0.04 ticks on an empty panel
            ax.set_xlim(0, 1)
        from matplotlib.ticker import MaxNLocator

        ax.xaxis.set_major_locator(MaxNLocator(integer=True))      # findings are counted
        ax.set_xlabel("findings")
        ax.set_title(f"acl lint {self.path}")
        return ax


# ------------------------------------------------------------------------------------------------
# acl.compile
# ------------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class SegmentRow:
    """One schedule segment: constant tones between ``start_s`` and ``end_s``."""

    start_s: float
    end_s: float
    step: int                                   #: program step, counted from 1 (as the CLI and segments.csv)
    goal: str | None
    tones: tuple[tuple[float, float], ...]      #: (frequency Hz, amplitude V peak) per tone


@dataclass
class Compiled:
    """A compiled program (:class:`acl.schedule.model.Schedule`) with typed segments and goals.

    ``as_dict()`` is the ``schedule.json`` that `acl compile` writes, without the ``waveform`` and
    ``files`` entries (no waveform is rendered here).
    """

    program: str                 #: program name
    duration_s: float            #: total duration (s)
    max_voltage_v: float         #: the amplifier / transducer limit the schedule respects (V peak)
    sample_rate_hz: float        #: rate the phases and peaks were computed for (S/s)
    segments: list[SegmentRow]   #: constant-tone segments on one time axis
    goals: list[dict]            #: per-goal promises: predicted error, margins (schedule.json ``goals``)
    schedule: Any = field(repr=False, default=None)   #: the :class:`acl.schedule.model.Schedule` itself

    @classmethod
    def from_schedule(cls, schedule) -> "Compiled":
        segs = [SegmentRow(s.start_s, s.end_s, s.step + 1, s.goal, tuple((t.frequency_hz, t.amplitude_v) for t in s.tones))
                for s in schedule.segments]
        return cls(schedule.program, schedule.duration_s, schedule.max_voltage_v, schedule.sample_rate_hz, segs,
                   [g.as_dict() for g in schedule.goals], schedule)

    def as_dict(self) -> dict:
        """schedule.json (docs/schedule.md) without the rendered-waveform entries.

        >>> import acl
        >>> acl.compile("examples/fig1f_selective_beams.acl", "sequential").as_dict()["duration_s"]
        3.0
        """
        from acl.emit.schedule_json import schedule_dict

        return schedule_dict(self.schedule, self.sample_rate_hz)

    def _repr_html_(self) -> str:
        rows = [[f"{s.start_s:.4g}", f"{s.end_s:.4g}", s.step, ", ".join(f"{f / 1e3:g} kHz @ {a:.3g} V" for f, a in s.tones)]
                for s in self.segments[:40]]
        more = f"{len(self.segments) - 40} more segments" if len(self.segments) > 40 else ""
        return html_table(f"program {self.program}: {self.duration_s:.4g} s, limit {self.max_voltage_v:g} V",
                          ["start (s)", "end (s)", "step", "tones"], rows, more)

    def plot(self, ax=None):
        """Amplitude (V peak) of each tone frequency over time, as steps.

        >>> import acl
        >>> ax = acl.compile("examples/fig1f_selective_beams.acl", "sequential").plot()
        >>> [t.get_text() for t in ax.get_legend().get_texts()]
        ['85 kHz', '170 kHz']
        """
        ax = new_axes(ax)
        freqs = sorted({f for s in self.segments for f, _ in s.tones})
        for f in freqs:
            t, v = [], []
            for s in self.segments:
                a = sum(amp for ff, amp in s.tones if ff == f)
                t += [s.start_s, s.end_s]
                v += [a, a]
            ax.plot(t, v, label=f"{f / 1e3:g} kHz")
        ax.axhline(self.max_voltage_v, ls="--", color="0.5", lw=1)
        ax.set_xlabel("time (s)")
        ax.set_ylabel("amplitude (V peak)")
        ax.set_title(f"program {self.program} (dashed: voltage limit)")
        if freqs:
            ax.legend(fontsize="small")
        return ax


# ------------------------------------------------------------------------------------------------
# acl.fit
# ------------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class FitParameter:
    """A fitted parameter after effect selection (docs/fit.md, report.json ``final.parameters``)."""

    name: str
    value: float
    unit: str
    low: float | None            #: 95 % interval, lower end
    high: float | None           #: 95 % interval, upper end


@dataclass
class FitReport:
    """What `acl fit --output-format json` prints, typed: RMSE before/after, selected effects, parameters.

    ``calibrated_source`` is the calibrated design's text (`acl fit --calibrated` writes it).
    """

    design: str                  #: design file fitted
    rows: int                    #: measurement rows used
    rmse_before: float | None    #: RMSE of the base model (SI units of the observable)
    rmse_after: float | None     #: RMSE with the selected effects
    effects_selected: list[str]  #: effects the selection kept
    parameters: list[FitParameter]   #: fitted parameters after selection, with 95 % intervals
    per_observable: dict         #: observable -> {n, rmse_before, rmse_after, unit}: "m", or "Pearson" (a latch state)
    calibrated_source: str = field(repr=False, default="")   #: text of the calibrated design
    _raw: dict = field(repr=False, default_factory=dict)

    @classmethod
    def from_outcome(cls, out) -> "FitReport":
        r = out.report
        params = [FitParameter(p["name"], p["value"], p.get("unit", ""), *(tuple(p.get("ci95") or (None, None))[:2]))
                  for p in r["final"]["parameters"]]
        per = {k: {"n": v["n"], "rmse_before": r["base"]["per_observable"][k]["rmse"], "rmse_after": v["rmse"],
                   "unit": v.get("unit", "m")}
               for k, v in r["final"]["per_observable"].items()}
        return cls(r["design"], r["rows"], r["rmse_before"], r["rmse_after"], list(r["effects_selected"]), params,
                   per, out.calibrated, r)

    def as_dict(self) -> dict:
        """The report.json object (docs/fit.md); examples: docs/python.md, section Fit."""
        return self._raw

    def _repr_html_(self) -> str:
        rows = [[p.name, f"{p.value:.4g}", p.unit, "-" if p.low is None else f"{p.low:.4g} .. {p.high:.4g}"]
                for p in self.parameters]
        note = (f"RMSE {_num(self.rmse_before, '{:.3g}', 1e6)} -> {_num(self.rmse_after, '{:.3g}', 1e6)} um; effects: "
                f"{', '.join(self.effects_selected) or 'none'}") if self.rmse_before is not None else ""
        return html_table(f"acl fit {self.design}: {self.rows} rows", ["parameter", "value", "unit", "95 % interval"],
                          rows, note)

    def plot(self, ax=None):
        """RMSE per observable before and after the fit (grouped bars): um for lengths, as `acl fit` prints them; a
        latch state's Pearson residual as it is."""
        import numpy as np

        ax = new_axes(ax)
        names = sorted(self.per_observable)
        x = np.arange(len(names))
        pearson = [self.per_observable[n].get("unit") == "Pearson" for n in names]
        scale = [1.0 if p else 1e6 for p in pearson]
        before = [(self.per_observable[n]["rmse_before"] or 0.0) * k for n, k in zip(names, scale)]
        after = [(self.per_observable[n]["rmse_after"] or 0.0) * k for n, k in zip(names, scale)]
        ax.bar(x - 0.2, before, 0.4, label="before")
        ax.bar(x + 0.2, after, 0.4, label="after")
        ax.set_xticks(x, [f"{n} (Pearson)" if p else n for n, p in zip(names, pearson)])
        ax.set_ylabel("RMSE (um; latch states: Pearson residual)" if any(pearson) else "RMSE (um)")
        ax.set_title("fit: error per observable")
        ax.legend(fontsize="small")
        return ax
