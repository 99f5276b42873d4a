"""The SCPI command stream that plays a schedule's drives on one generator through one amplifier.

Two forms (docs/bench.md):

- **sequence**: the generator holds one short looped segment per distinct constant drive (a whole
  number of periods of its tones, :mod:`acl.emit.seq`) and a sequence that repeats each segment for
  its drive's duration: timed by the instrument.  Used where the generator has a sequence mode and
  every drive loops exactly within its memory.
- **steps**: one channel per tone (a sine), amplitude (and frequency) set at each drive's start:
  timed by the host.  The channels are summed into the amplifier input (the Keysight combines
  channel 2 into output 1; the AFG-2225's outputs need an external summing junction).

Every setting is followed by its query: :mod:`acl.bench.player` compares the answer with what was set.
The chain check refuses (E-PLAY-CHAIN) a drive beyond the amplifier's output, the generator's
output or frequency range, the amplifier's bandwidth, or with more simultaneous tones than channels.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from acl.bench.chain import Amplifier, Generator
from acl.diagnostics import DiagnosticError, Span, error
from acl.emit.seq import Drive, common_frequency, loop_rate, loop_samples


@dataclass(frozen=True)
class Setting:
    """One SCPI message, and the query that reads it back with the answer expected."""

    command: str
    query: str | None = None
    expect: str | float | None = None       # a number (compared within ``tol``) or a word
    tol: float = 0.0


@dataclass
class Step:
    at_s: float | None                      # seconds after the start (None: before the start)
    settings: list[Setting] = field(default_factory=list)


@dataclass
class Plan:
    generator: Generator
    amplifier: Amplifier
    form: str                               # "sequence" or "steps"
    setup: Step
    steps: list[Step]
    stop: Step                              # every output off (also run on any error)
    notes: list[str] = field(default_factory=list)
    duration_s: float = 0.0

    def stream(self) -> str:
        """The command stream as sent (queries included), ``#`` comments for timing and notes."""
        out = [f"# acl play: {self.generator.name} -> {self.amplifier.name} (gain {self.amplifier.gain:g}), "
               f"form: {self.form}"]
        out += [f"# note: {n}" for n in self.notes]
        for step in [self.setup, *self.steps, self.stop]:
            if step is self.stop:
                out.append("SYST:ERR?")          # the player's check of the error queue
                out.append(f"# t={self.duration_s:.6g} s: stop")
            elif step.at_s is not None:
                out.append(f"# t={step.at_s:.6g} s")
            for s in step.settings:
                out.append(s.command)
                if s.query:
                    out.append(s.query)
            if step is self.setup:
                out.append("SYST:ERR?")
        return "\n".join(out) + "\n"


def _fmt(x: float, digits: int) -> str:
    text = f"{x:.{digits}f}"
    return text.rstrip("0").rstrip(".") if "." in text else text


def number_setting(cmd: str, query: str, value: float, digits: int) -> Setting:
    text = _fmt(value, digits)
    return Setting(f"{cmd} {text}", query, float(text), 0.5 * 10 ** -digits + 1e-12 * abs(float(text)))


class _Dialect:
    """Spellings of one SCPI family."""

    def __init__(self, dialect: str):
        self.d = dialect

    def func(self, c, name):
        return Setting(f"SOUR{c}:FUNC {name}", f"SOUR{c}:FUNC?", name)

    def freq(self, c, f):
        return number_setting(f"SOUR{c}:FREQ", f"SOUR{c}:FREQ?", f, 3)

    def vpp(self, c, v, digits):
        cmd = "AMP" if self.d == "afg2200" else "VOLT"
        return number_setting(f"SOUR{c}:{cmd}", f"SOUR{c}:{cmd}?", v, digits)

    def offset(self, c):
        cmd = "DCO" if self.d == "afg2200" else "VOLT:OFFS"
        return number_setting(f"SOUR{c}:{cmd}", f"SOUR{c}:{cmd}?", 0.0, 4)

    def output(self, c, on):
        return Setting(f"OUTP{c} {'ON' if on else 'OFF'}", f"OUTP{c}?", "ON" if on else "OFF")

    def load(self, c):
        return Setting(f"OUTP{c}:LOAD INF", f"OUTP{c}:LOAD?", "INF")


def _refuse(meta, i, message, hint=None):
    line, col = meta["locations"][i] if i is not None and i < len(meta.get("locations", [])) else (1, 1)
    return error("E-PLAY-CHAIN", message, Span(file=meta.get("path", "<schedule>"), line=line, column=col), hint)


def check_chain(drives: list[Drive], meta: dict, gen: Generator, amp: Amplifier) -> list:
    """Errors (E-PLAY-CHAIN, at the drive's segment) for drives the chain cannot deliver."""
    diags = []
    for i, d in enumerate(drives):
        peak = sum(a for _, a, _ in d.tones)
        fmax = max((f for f, _, _ in d.tones), default=0.0)
        if d.swept:
            diags.append(_refuse(meta, i, f"the drive at {d.start_s:g} s sweeps a tone: acl play sends "
                                 "constant tones only", "play the WAV of `acl compile` from an arbitrary "
                                 "waveform generator instead"))
        elif peak > amp.max_output_v * (1 + 1e-9):
            diags.append(_refuse(meta, i, f"the drive at {d.start_s:g} s peaks at {peak:.4g} V: beyond the "
                                 f"{amp.name}'s {amp.max_output_v:g} V output", "lower the schedule's voltages "
                                 "(the transducer's max_voltage) or use another amplifier"))
        elif peak / amp.gain > min(amp.max_input_v, gen.max_vpp / 2) * (1 + 1e-9):
            diags.append(_refuse(meta, i, f"the drive at {d.start_s:g} s needs {peak / amp.gain:.4g} V peak from "
                                 f"the generator: beyond {min(amp.max_input_v, gen.max_vpp / 2):g} V (the "
                                 f"{gen.name}'s output or the {amp.name}'s input)"))
        elif fmax > min(amp.bandwidth_hz, gen.max_frequency_hz):
            diags.append(_refuse(meta, i, f"the drive at {d.start_s:g} s has a {fmax:g} Hz tone: beyond the "
                                 f"chain's bandwidth ({min(amp.bandwidth_hz, gen.max_frequency_hz):g} Hz)"))
        if len(diags) >= 20:
            break
    return diags


def _active(d: Drive, gen: Generator, amp: Amplifier):
    """Tones of ``d`` the generator can set (>= its smallest amplitude), and the largest dropped one."""
    keep, dropped = [], 0.0
    for f, a, p in d.tones:
        vpp = 2 * a / amp.gain
        if vpp >= gen.min_vpp:
            keep.append((f, vpp))
        else:
            dropped = max(dropped, a)
    return keep, dropped


def plan(drives: list[Drive], meta: dict, gen: Generator, amp: Amplifier, form: str | None = None) -> Plan:
    """The plan of the best form the generator has (``form`` forces one); DiagnosticError if none."""
    diags = check_chain(drives, meta, gen, amp)
    if diags:
        raise DiagnosticError(diags)
    duration = drives[-1].start_s + drives[-1].duration_s
    if form in (None, "sequence") and gen.sequence:
        p = _sequence(drives, meta, gen, amp, duration)
        if p is not None or form == "sequence":
            if p is None:
                raise DiagnosticError([_refuse(meta, None, f"the {gen.name} cannot hold this schedule as a "
                                               "sequence of looped segments (tones not whole hertz, or over "
                                               "its memory or sequence length)", "play it in steps")])
            return p
    if form == "sequence":
        raise DiagnosticError([_refuse(meta, None, f"the {gen.name} has no sequence mode")])
    return _steps(drives, meta, gen, amp, duration)


def _steps(drives, meta, gen: Generator, amp: Amplifier, duration: float) -> Plan:
    dl = _Dialect(gen.dialect)
    channels = list(range(1, gen.channels + 1))
    chan_freq: dict[int, float | None] = {c: None for c in channels}
    chan_vpp: dict[int, float | None] = {c: None for c in channels}
    chan_on = {c: False for c in channels}
    used: set[int] = set()
    dropped = 0.0
    per_drive = []
    for i, d in enumerate(drives):
        keep, drop = _active(d, gen, amp)
        dropped = max(dropped, drop)
        if len(keep) > gen.channels:
            raise DiagnosticError([_refuse(meta, i, f"the drive at {d.start_s:g} s plays {len(keep)} tones at "
                                           f"once: the {gen.name} has {gen.channels} channels and no sequence "
                                           "mode", "use a generator with a sequence mode (e.g. --instrument 33522b)")])
        assign: dict[int, tuple[float, float]] = {}
        free = [c for c in channels]
        rest = []
        for f, vpp in keep:                     # a tone stays on the channel already at its frequency
            c = next((c for c in free if chan_freq[c] is not None and abs(chan_freq[c] - f) < 1e-6), None)
            if c is None:
                rest.append((f, vpp))
            else:
                assign[c] = (f, vpp)
                free.remove(c)
        for f, vpp in rest:
            c = free.pop(0)
            assign[c] = (f, vpp)
        per_drive.append(assign)
        for c, (f, _) in assign.items():
            used.add(c)
            chan_freq[c] = f if chan_freq[c] is None else chan_freq[c]
    used_channels = sorted(used) or [1]
    setup = Step(None)
    for c in channels:
        setup.settings.append(dl.output(c, False))
    chan_freq = {c: None for c in channels}
    for c in used_channels:      # a combining Keysight's tone is off as 0 V DC (output 1 carries both)
        setup.settings += [dl.func(c, "DC" if gen.combine else "SIN"), dl.load(c), dl.offset(c)]
    if gen.combine and len(used_channels) > 1:
        setup.settings.append(Setting("SOUR1:COMB:FEED CH2", "SOUR1:COMB:FEED?", "CH2"))
    steps = []
    for d, assign in zip(drives, per_drive):
        step = Step(d.start_s)
        for c in used_channels:
            if c in assign:
                f, vpp = assign[c]
                if chan_freq[c] is None or abs(chan_freq[c] - f) > 1e-6:
                    step.settings.append(dl.freq(c, f))
                    chan_freq[c] = f
                s = dl.vpp(c, vpp, gen.vpp_digits)
                if chan_vpp[c] is None or abs(chan_vpp[c] - s.expect) > 1e-12:
                    step.settings.append(s)
                    chan_vpp[c] = s.expect
                if not chan_on[c]:
                    step.settings.append(_on(dl, gen, c, True))
                    chan_on[c] = True
            elif chan_on[c]:
                step.settings.append(_on(dl, gen, c, False))
                chan_on[c] = False
        if gen.combine and not steps:
            step.settings.append(dl.output(1, True))
        if step.settings:
            steps.append(step)
    stop = Step(duration, [dl.output(c, False) for c in channels])
    notes = []
    if dropped > 0:
        notes.append(f"tones under the generator's {gen.min_vpp * 1e3:g} mVpp are off: the largest is "
                     f"{dropped:.3g} V at the transducer")
    if len(used_channels) > 1:
        notes.append("channels 1 and 2 are added into output 1 (channel combine)" if gen.combine else
                     "outputs 1 and 2 must be added into the amplifier input by a unity-gain summing junction")
    notes.append(f"host-timed steps: {len(steps)} changes over {duration:.6g} s; amplitudes in Vpp at the "
                 f"generator = 2 x peak / {amp.gain:g}, to {10 ** -gen.vpp_digits:g} V")
    return Plan(gen, amp, "steps", setup, steps, stop, notes, duration)


def _on(dl: _Dialect, gen: Generator, c: int, on: bool) -> Setting:
    """A tone on or off: the output (AFG-2225), or on a combining Keysight sine or 0 V DC (output 1
    carries both channels, so channel 2 cannot be switched by its own output)."""
    if gen.combine:
        return dl.func(c, "SIN" if on else "DC")
    return dl.output(c, on)


def _sequence(drives, meta, gen: Generator, amp: Amplifier, duration: float) -> Plan | None:
    sounding = [d for d in drives if d.tones]
    rate = loop_rate(sounding, gen.sample_rate_max) if sounding else None
    if rate is None:
        return None
    distinct: dict[tuple, int] = {}
    for d in sounding:
        distinct.setdefault(d.tones, len(distinct))
    points = {}
    for tones, k in distinct.items():
        g = common_frequency(f for f, _, _ in tones)
        n = round(rate / g)
        n *= max(1, math.ceil(gen.min_segment_points / n))
        points[k] = n
    silent = gen.min_segment_points
    if sum(points.values()) + silent > gen.memory_points or len(drives) + 1 > gen.max_sequence_steps:
        return None
    vmax = max(max(abs(loop_samples(t, rate, points[k])).max() for t, k in distinct.items()) / amp.gain,
               gen.min_vpp / 2)
    vmax = float(_fmt(2 * vmax + 0.5 * 10 ** -gen.vpp_digits, gen.vpp_digits)) / 2    # rounded up to a setting
    dl = _Dialect(gen.dialect)
    setup = Step(None, [dl.output(1, False), Setting("SOUR1:DATA:VOL:CLE")])
    for tones, k in distinct.items():
        v = loop_samples(tones, rate, points[k]) / amp.gain
        dac = [int(round(32767 * x / vmax)) for x in v]
        name = f"ACL{k + 1}"
        setup.settings.append(Setting(f"SOUR1:DATA:ARB:DAC {name}," + ",".join(map(str, dac)),
                                      f"SOUR1:DATA:ATTR:POIN? {name}", float(points[k]), 0.0))
    setup.settings.append(Setting("SOUR1:DATA:ARB:DAC ACL0," + ",".join(["0"] * silent),
                                  "SOUR1:DATA:ATTR:POIN? ACL0", float(silent), 0.0))
    entries, carry = [], 0.0
    for d in drives:
        if d.tones:
            k = distinct[d.tones]
            period = points[k] / rate
        else:
            k, period = -1, silent / rate
        want = d.duration_s + carry                      # the rounding carried on: the total time stays exact
        count = max(1, round(want / period))
        carry = want - count * period
        entries.append(f'"ACL{k + 1}",{count},repeat,maintain,4')
    entries.append('"ACL0",0,repeatInf,maintain,4')      # silent after the last drive
    body = '"ACLSEQ",' + ",".join(entries)
    block = f"#{len(str(len(body)))}{len(body)}{body}"
    setup.settings += [
        Setting(f"SOUR1:DATA:SEQ {block}"),
        Setting("SOUR1:FUNC ARB", "SOUR1:FUNC?", "ARB"),
        Setting("SOUR1:FUNC:ARB ACLSEQ", "SOUR1:FUNC:ARB?", "ACLSEQ"),
        number_setting("SOUR1:FUNC:ARB:SRAT", "SOUR1:FUNC:ARB:SRAT?", rate, 0),
        dl.load(1),
        number_setting("SOUR1:VOLT", "SOUR1:VOLT?", 2 * vmax, gen.vpp_digits),
        dl.offset(1),
    ]
    start = Step(0.0, [dl.output(1, True)])
    stop = Step(duration, [dl.output(1, False)])
    notes = [f"instrument-timed: {len(distinct)} looped segments ({sum(points.values())} points at "
             f"{rate:g} S/s) in a sequence of {len(drives)} steps; the last step's rounding leaves the "
             f"total within {0.5 * max(points.values()) / rate:.3g} s",
             f"DAC full scale = {vmax:.4g} V peak at the generator ({vmax * amp.gain:.4g} V at the transducer)"]
    return Plan(gen, amp, "sequence", setup, [start], stop, notes, duration)
