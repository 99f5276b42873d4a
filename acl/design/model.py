"""The resolved design: immutable pydantic models, SI floats, each element with its source span.

This is the contract between the language front-end and every later stage (physics, analysis,
schedule, lint, fit).  Later stages never see syntax: only these models.

Conventions
-----------
* Every float is in SI base units (m, kg, s, Pa, N, V, Hz, rad).  Field names say the quantity;
  the unit is SI unless the name says otherwise.
* Vectors are 3-tuples in the one design frame: substrate plane z = 0, z up.
* Tone amplitudes are *peak* voltages at the transducer input.
* ``span`` points at the declaration (file:line:column) so that findings can point at it.
* Names are fully qualified for imported elements (``pbs.water``), plain for local ones.
"""
from __future__ import annotations

import functools
import math
from typing import Annotated, Literal, Union

from pydantic import BaseModel, ConfigDict, Field

from acl.diagnostics import Span

Vec3 = tuple[float, float, float]


class Frozen(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")


# ----------------------------------------------------------------------------------------------
# Parameters and environment
# ----------------------------------------------------------------------------------------------

class Spread(Frozen):
    """The distribution of a parameter's deviation from its value (docs/sweep.md, section 2).

    ``+- normal(mean, sd)``: ``a`` = mean, ``b`` = standard deviation; ``+- uniform(lo, hi)``:
    ``a`` = lo, ``b`` = hi (offsets from the value, lo <= hi).  ``relative``: ``a`` and ``b`` are
    fractions of the value's magnitude (``+- 3 %`` is ``normal(0, 3 %)``); otherwise SI, in the
    value's unit.  ``lognormal`` (a parameter an ``uncertainty { lognormal(p) }`` entry names; not
    written as a spread): relative, ``b`` = the coefficient of variation, the value its mean.
    """

    kind: Literal["normal", "uniform", "lognormal"]
    a: float
    b: float
    relative: bool = False

    def stddev(self, value: float) -> float:
        """Standard deviation (SI) about a value: sd, or (hi - lo)/sqrt(12) for a uniform spread."""
        s = self.b if self.kind in ("normal", "lognormal") else (self.b - self.a) / math.sqrt(12.0)
        return abs(value) * s if self.relative else s


class Param(Frozen):
    """``param NAME = expr [+- spread] [free [in lo .. hi]]``; value in SI, ``unit`` the SI unit string.

    ``stddev`` (same unit as the value) is the declared standard deviation of the value, None when
    the value is taken as exact; correlations between parameters are in ``Design.correlations``.
    ``spread`` is the declared distribution when it is more than ``+- sd`` (a normal of mean 0):
    ``+- normal(mean, sd)``, ``+- uniform(lo, hi)`` or relative ``+- 3 %``; None otherwise.
    """

    name: str
    value: float
    unit: str = ""                 # SI unit string of the value, e.g. "N/V^2", "m", "" (dimensionless)
    free: bool = False
    lower: float | None = None
    upper: float | None = None
    stddev: float | None = None
    spread: Spread | None = None
    span: Span

    def distribution(self) -> Spread | None:
        """The declared spread, ``+- sd`` as ``normal(0, sd)``; None when the value is exact."""
        if self.spread is not None:
            return self.spread
        return Spread(kind="normal", a=0.0, b=self.stddev) if self.stddev else None


class Correlation(Frozen):
    """``correlation(a, b) = r`` in an ``uncertainty { }`` block: correlation of two uncertain parameters."""

    a: str
    b: str
    value: float                   # in [-1, 1]
    span: Span


class Coverage(Frozen):
    """``covered(QUANTITY) = lo .. hi``: the range a calibration's data covered (SI).

    ``quantity`` is ``voltage`` (sum of tone amplitudes, V), ``frequency`` (Hz) or ``deflection`` (m).
    """

    quantity: Literal["voltage", "frequency", "deflection"]
    lower: float
    upper: float
    span: Span


class MeasuredGain(Frozen):
    """``measured(gain) = [(f, s), ...]`` or ``[(f, g, s), ...]``: the transducer gain at tone ``f`` (Hz) was measured.

    ``gain`` (Pa/V, optional) is the gain-table value measured at the tone: the resolved transducer's table
    carries it as a point there (:func:`with_measured_gain`), so the analysis, compile and sweep use it; ``acl
    fit`` writes the gain its data ask for at each tone they drove.  ``stddev`` is its relative standard deviation
    (log scale), all fitted coefficients free: what the data leave unknown there.  The error bands of a compile
    hold the gain table at such a tone to that value (times ``exp(stddev z)``) instead of the table's prior
    ``gain_uncertainty`` (acl.schedule.bands).
    """

    frequency: float
    stddev: float
    gain: float | None = None      # Pa/V: a table point measured at the tone (None: the table's value is kept)
    span: Span


class Medium(Frozen):
    """Liquid around the bubbles and the gas inside them."""

    name: str
    density: float                 # kg/m^3 (liquid)
    viscosity: float               # Pa s (dynamic, liquid)
    sound_speed: float             # m/s (liquid)
    surface_tension: float         # N/m
    ambient_pressure: float        # Pa
    polytropic_index: float        # gas, dimensionless (1 isothermal .. 1.4 adiabatic air)
    gas_thermal_diffusivity: float = 2.1e-5   # m^2/s (air at 20 C); used for thermal damping
    span: Span


class Material(Frozen):
    name: str
    youngs_modulus: float          # Pa
    poisson_ratio: float
    density: float                 # kg/m^3
    span: Span


class Transducer(Frozen):
    """Pressure per volt vs frequency (table, sorted by frequency), usable band and maximum voltage."""

    name: str
    max_voltage: float             # V (peak)
    band: tuple[float, float]      # Hz
    gain_frequencies: tuple[float, ...]    # Hz, strictly increasing
    gain_pa_per_v: tuple[float, ...]       # Pa/V (pressure amplitude per volt amplitude)
    gain_uncertainty: float | None = None  # relative standard deviation of each table value (independent)
    span: Span


def with_measured_gain(transducer: Transducer | None, measured) -> Transducer | None:
    """The transducer with a table point at each tone a ``measured(gain)`` entry gives a gain for (a table point
    already at that tone is replaced): the measured value wins over the declared table there."""
    knots = [(m.frequency, m.gain) for m in measured if m.gain is not None]
    if transducer is None or not knots:
        return transducer
    table = dict(zip(transducer.gain_frequencies, transducer.gain_pa_per_v))
    for f, g in knots:
        for k in [k for k in table if abs(k - f) <= 1e-9 * f]:
            del table[k]
        table[f] = g
    fs = tuple(sorted(table))
    return transducer.model_copy(update={"gain_frequencies": fs, "gain_pa_per_v": tuple(table[f] for f in fs)})


class Generator(Frozen):
    """The signal generator of the drive chain (datasheet values): its largest peak output voltage,
    and optionally its arbitrary-waveform sample rate and memory, channels and highest frequency."""

    name: str
    max_voltage: float                     # V peak (into the amplifier's input)
    sample_rate: float | None = None       # S/s
    memory: float | None = None            # points
    channels: int = 1
    max_frequency: float | None = None     # Hz
    span: Span


class Amplifier(Frozen):
    """The amplifier between generator and transducer: voltage gain, largest peak output, bandwidth."""

    name: str
    gain: float                            # V/V
    max_voltage: float                     # V peak at its output
    bandwidth: float | None = None         # Hz
    span: Span


# ----------------------------------------------------------------------------------------------
# Capsules (bubble actuators)
# ----------------------------------------------------------------------------------------------

class Cavity(Frozen):
    """Cavity holding the bubble; ``volume`` is the gas volume (m^3) whatever the shape.

    ``shape`` is ``cylinder`` (radius, height, axis), ``prism`` (equilateral triangular prism:
    side, height, axis) or ``volume`` (only the volume is given).
    """

    shape: Literal["cylinder", "prism", "volume"]
    volume: float
    radius: float | None = None    # cylinder
    side: float | None = None      # prism (edge of the triangle)
    height: float | None = None    # cylinder / prism, along ``axis``
    axis: Vec3 = (0.0, 0.0, 1.0)
    wall: float = 2e-6             # wall thickness (m), for printability and outer extent


class Orifice(Frozen):
    name: str                      # local name inside its capsule, e.g. "jet"
    radius: float                  # m
    normal: Vec3                   # outward unit normal
    center: Vec3                   # absolute position of the orifice centre (rest configuration)
    span: Span


class Capsule(Frozen):
    name: str
    cavity: Cavity
    orifices: tuple[Orifice, ...]
    center: Vec3                   # cavity centre, rest configuration
    # Optional model coefficients (declared or written by `acl fit`); None = predict from physics.
    thrust_coefficient: float | None = None   # gamma, N/V^2 (thrust = gamma V^2 at resonance drive)
    quality_factor: float | None = None       # overrides predicted damping of every mode
    span: Span

    def orifice(self, name: str) -> Orifice:
        for o in self.orifices:
            if o.name == name:
                return o
        raise KeyError(name)


# ----------------------------------------------------------------------------------------------
# Structures
# ----------------------------------------------------------------------------------------------

class Section(Frozen):
    shape: Literal["circle", "rect"]
    diameter: float | None = None  # circle
    width: float | None = None     # rect, in the bending plane normal to ``bend`` direction
    thickness: float | None = None

    @property
    def area(self) -> float:
        if self.shape == "circle":
            return math.pi * self.diameter**2 / 4
        return self.width * self.thickness

    @property
    def second_moment(self) -> float:
        """Smallest second moment of area (m^4)."""
        if self.shape == "circle":
            return math.pi * self.diameter**4 / 64
        a, b = sorted((self.width, self.thickness))
        return b * a**3 / 12

    @property
    def min_feature(self) -> float:
        return self.diameter if self.shape == "circle" else min(self.width, self.thickness)


class Beam(Frozen):
    """Cantilever clamped at ``clamp`` pointing along ``axis``; tip = clamp + length * axis."""

    name: str
    length: float
    section: Section
    material: str                  # material name (key of Design.materials)
    youngs_modulus: float          # Pa, copied from the material (after overrides)
    clamp: Vec3
    axis: Vec3
    tip: Vec3
    rigid_length: float = 0.0      # l of paper Eq. (1): half the rigid actuator length at the tip
    span: Span

    @property
    def bending_stiffness(self) -> float:
        return self.youngs_modulus * self.section.second_moment


class Spring(Frozen):
    """A flexure: linear stiffness (N/m) along ``axis``; given directly or derived from geometry."""

    name: str
    stiffness: float
    axis: Vec3
    span: Span


class Truss(Frozen):
    """A rigid link between two points."""

    name: str
    span: Span


class Latch(Frozen):
    """Bistable inclined-beam mechanism (paper Fig. 6a): two inclined beams and a shuttle.

    The shuttle moves along ``axis``; ``state`` is the rest state, ``"a"`` (initial, as printed)
    or ``"b"`` (snapped through).
    """

    name: str
    angle: float                   # rad, inclination theta
    length: float                  # m, beam length L
    width: float                   # m, in-plane width w (bending)
    thickness: float               # m, out-of-plane thickness
    material: str
    youngs_modulus: float
    anchor: Vec3                   # shuttle rest position
    axis: Vec3                     # actuation direction (unit)
    state: Literal["a", "b"] = "a"
    span: Span


class Anchor(Frozen):
    name: str
    position: Vec3
    span: Span


# ----------------------------------------------------------------------------------------------
# Joints
# ----------------------------------------------------------------------------------------------

class Mount(Frozen):
    """A capsule carried by a beam tip, a latch shuttle or a spring end."""

    kind: Literal["mount"] = "mount"
    capsule: str
    target: str                    # element name
    target_kind: Literal["beam", "latch", "spring"]
    span: Span


class Fix(Frozen):
    """A capsule fixed to the substrate (ground)."""

    kind: Literal["fix"] = "fix"
    capsule: str
    span: Span


class Link(Frozen):
    """Two points (capsules or anchors, or 'ground') linked by a truss or a spring."""

    kind: Literal["link"] = "link"
    a: str
    b: str                         # capsule / anchor name or "ground"
    element: str                   # truss or spring name
    element_kind: Literal["truss", "spring"]
    span: Span


Joint = Annotated[Union[Mount, Fix, Link], Field(discriminator="kind")]


# ----------------------------------------------------------------------------------------------
# Observations and requirements
# ----------------------------------------------------------------------------------------------

class Observe(Frozen):
    """A measurable quantity.

    kind ``displacement``: of ``target`` (beam name -> its tip, or capsule name) along ``axis``.
    kind ``gap``: distance between two orifices' vibrating surfaces; ``a``/``b`` are
    ``capsule.orifice``.  kind ``position``: planar coordinate ``component`` ("x"|"y"|"z") of a
    capsule centre.  kind ``state``: the state of latch ``target``, 0 (state a, as printed) or 1
    (state b, snapped through).
    """

    name: str
    kind: Literal["displacement", "gap", "position", "state"]
    target: str | None = None
    axis: Vec3 | None = None
    a: str | None = None
    b: str | None = None
    component: Literal["x", "y", "z"] | None = None
    span: Span


class Require(Frozen):
    """Design intent checked by `acl analyze` and lint.

    kind ``resonance``: capsule's mode ``mode`` (0-based) frequency in [lower, upper] Hz.
    kind ``separation``: |f(a) - f(b)| >= lower Hz (first modes of capsules a and b); with one
    capsule, the smallest distance between its adjacent modes (as `acl analyze` lists them).
    kind ``margin``: latch switching margin >= lower (dimensionless).
    kind ``gap``: gap(a, b) >= lower (m) under every program step.
    """

    kind: Literal["resonance", "separation", "margin", "gap"]
    args: tuple[str, ...]
    mode: int = 0
    lower: float | None = None
    upper: float | None = None
    text: str
    span: Span


# ----------------------------------------------------------------------------------------------
# Programs
# ----------------------------------------------------------------------------------------------

class Tone(Frozen):
    frequency: float               # Hz
    amplitude: float               # V, peak
    phase: float = 0.0             # rad
    phase_given: bool = False      # the user wrote `phase ...`: the compiler keeps it as it is


class Drive(Frozen):
    tones: tuple[Tone, ...]


class Limits(Frozen):
    max_voltage: float | None = None     # V peak, total
    slew_rate: float | None = None       # V/s per tone amplitude


class DriveStep(Frozen):
    kind: Literal["drive"] = "drive"
    drive: Drive
    duration: float
    limits: Limits = Limits()      # the step's `limit` (its amplitudes add up to at most it)
    span: Span


class SweepStep(Frozen):
    kind: Literal["sweep"] = "sweep"
    f_start: float
    f_stop: float
    amplitude: float
    duration: float
    log: bool = False
    span: Span


class PauseStep(Frozen):
    kind: Literal["pause"] = "pause"
    duration: float
    span: Span


class PathSpec(Frozen):
    """A planar path, coordinates in m relative to the followed capsule's rest position.

    shape ``line``/``polyline``/``csv``: ``points``; ``rectangle``: width, height, center;
    ``circle``: radius, center; ``text``: text, height, center.  Sampling lives in acl.design.paths.
    """

    shape: Literal["line", "polyline", "rectangle", "circle", "text", "csv"]
    points: tuple[tuple[float, float], ...] = ()
    width: float | None = None
    height: float | None = None
    radius: float | None = None
    center: tuple[float, float] = (0.0, 0.0)
    text: str | None = None
    source: str | None = None      # csv path as resolved


class FollowStep(Frozen):
    kind: Literal["follow"] = "follow"
    capsule: str
    path: PathSpec
    duration: float | None = None
    speed: float | None = None     # m/s; one of duration/speed is set
    tones: tuple[float, ...] = ()  # Hz, pinned by the user; empty = compiler chooses
    limits: Limits = Limits()
    span: Span


class SwitchStep(Frozen):
    kind: Literal["switch"] = "switch"
    latch: str
    state: Literal["a", "b"]
    margin: float = 1.2
    tones: tuple[float, ...] = ()
    duration: float = 0.1
    limits: Limits = Limits()
    span: Span


class HoldStep(Frozen):
    """Hold gap(a, b) above ``bound`` (mode "above") or drive it below snap-in (mode "cross")."""

    kind: Literal["hold"] = "hold"
    a: str
    b: str
    mode: Literal["above", "cross"] = "above"
    bound: float | None = None
    margin: float = 1.2            # safety factor on the snap-in voltage (above) or beyond it (cross)
    duration: float
    tones: tuple[float, ...] = ()
    limits: Limits = Limits()
    span: Span


Step = Annotated[Union[DriveStep, SweepStep, PauseStep, FollowStep, SwitchStep, HoldStep],
                 Field(discriminator="kind")]


class Program(Frozen):
    name: str
    steps: tuple[Step, ...]
    span: Span


class Effect(Frozen):
    """A physical effect added to the base model (written by `acl fit`, or declared by hand).

    ``name`` is the effect's stable identifier (see docs/fit.md, e.g. ``drive_saturation``);
    ``params`` its coefficients in SI, ``units`` their SI unit strings.
    """

    name: str
    params: dict[str, float]
    units: dict[str, str] = {}
    span: Span


# ----------------------------------------------------------------------------------------------
# The whole design
# ----------------------------------------------------------------------------------------------

class Design(Frozen):
    file: str
    params: tuple[Param, ...] = ()
    medium: Medium | None = None
    transducer: Transducer | None = None
    generator: Generator | None = None
    amplifier: Amplifier | None = None
    materials: tuple[Material, ...] = ()
    capsules: tuple[Capsule, ...] = ()
    beams: tuple[Beam, ...] = ()
    springs: tuple[Spring, ...] = ()
    trusses: tuple[Truss, ...] = ()
    latches: tuple[Latch, ...] = ()
    anchors: tuple[Anchor, ...] = ()
    joints: tuple[Joint, ...] = ()
    observes: tuple[Observe, ...] = ()
    requires: tuple[Require, ...] = ()
    programs: tuple[Program, ...] = ()
    effects: tuple[Effect, ...] = ()
    correlations: tuple[Correlation, ...] = ()
    coverage: tuple[Coverage, ...] = ()
    discrepancy: float | None = None   # m: RMS difference of the calibrated model from its data (uncertainty block)
    measured_gain: tuple[MeasuredGain, ...] = ()   # tones whose transducer gain a calibration measured (uncertainty block)
    lognormal: tuple[str, ...] = ()    # uncertain parameters drawn log-normal (positive; uncertainty block)
    sources: tuple[str, ...] = ()  # every file read (design, imports, csv), in order

    # -- lookups -------------------------------------------------------------------------------
    def capsule(self, name: str) -> Capsule:
        return _find(self._index["capsules"], name, "capsule")

    def beam(self, name: str) -> Beam:
        return _find(self._index["beams"], name, "beam")

    def latch(self, name: str) -> Latch:
        return _find(self._index["latches"], name, "latch")

    def spring(self, name: str) -> Spring:
        return _find(self._index["springs"], name, "spring")

    def program(self, name: str) -> Program:
        return _find(self._index["programs"], name, "program")

    def param(self, name: str) -> Param:
        return _find(self._index["params"], name, "param")

    def material(self, name: str) -> Material:
        return _find(self._index["materials"], name, "material")

    def observe(self, name: str) -> Observe:
        return _find(self._index["observes"], name, "observe")

    def effect(self, name: str) -> Effect | None:
        """The declared effect with this identifier, or None."""
        return next((e for e in self.effects if e.name == name), None)

    def uncertain_params(self) -> tuple[Param, ...]:
        """The parameters that declare a standard deviation (``+- s``), in declaration order."""
        return tuple(p for p in self.params if p.stddev)

    def covariance(self, names=None):
        """Covariance matrix (SI) of the uncertain parameters ``names`` (default all), from ``+- s`` and correlations."""
        import numpy as np

        ps = [self.param(n) for n in names] if names is not None else list(self.uncertain_params())
        sd = np.array([p.stddev or 0.0 for p in ps])
        corr = np.eye(len(ps))
        pos = {p.name: i for i, p in enumerate(ps)}
        for c in self.correlations:
            if c.a in pos and c.b in pos:
                corr[pos[c.a], pos[c.b]] = corr[pos[c.b], pos[c.a]] = c.value
        return corr * np.outer(sd, sd)

    def mount_of(self, capsule: str):
        """The joint that holds ``capsule`` (Mount or Fix), or None if it floats."""
        return self._index["holds"].get(capsule)

    @functools.cached_property
    def _index(self) -> dict:
        """Name -> element per kind, built once (the model is frozen, so it never goes stale)."""
        idx = {kind: {it.name: it for it in getattr(self, kind)}
               for kind in ("capsules", "beams", "latches", "springs", "programs", "params", "materials", "observes")}
        holds = {}
        for j in self.joints:
            if j.kind in ("mount", "fix") and j.capsule not in holds:
                holds[j.capsule] = j
        idx["holds"] = holds
        return idx

    def summary(self) -> str:
        parts = [f"{len(self.capsules)} capsules", f"{len(self.beams)} beams"]
        if self.latches:
            parts.append(f"{len(self.latches)} latches")
        if self.springs:
            parts.append(f"{len(self.springs)} springs")
        parts.append(f"{len(self.programs)} programs")
        return ", ".join(parts)

    def __repr__(self) -> str:  # readable in notebooks
        return f"<Design {self.file}: {self.summary()}>"

    def _repr_html_(self) -> str:
        """Notebook display: a compact table of the elements (acl.notebook)."""
        from acl.notebook import design_html

        return design_html(self)

    def plot(self, ax=None):
        """Top view of beams and capsules on ``ax`` (or a new Figure, backend untouched); returns the Axes."""
        from acl.notebook import plot_design

        return plot_design(self, ax)


def _find(index: dict, name: str, what: str):
    try:
        return index[name]
    except KeyError:
        raise KeyError(f"no {what} named {name!r}") from None
