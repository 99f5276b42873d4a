"""Checks on the resolved design: geometry, printability, attachments, and programs vs transducer."""
from __future__ import annotations

import math

from acl.design import geometry as G
from acl.design import model as M
from acl.diagnostics import DiagnosticBag

# Two-photon lithography resolution, paper Supplementary Note 1 (0.2 um lateral hatching, 0.3 um slicing).
PRINT_LATERAL = 0.2e-6
PRINT_AXIAL = 0.3e-6
SLENDERNESS = (3.0, 500.0)   # beam length / smallest section size for Euler-Bernoulli beams to be sane
OVERLAP_TOL = 0.5e-6


PRINT_VOLUME = 1.0   # m: no coordinate or beam length of a printed micro-mechanism comes near it


def check_design_geometry(design: M.Design, bag: DiagnosticBag, specs: dict) -> None:
    if not _inside_print_volume(design, bag):
        return    # absurd sizes: distances would overflow, the other checks mean nothing
    _printability(design, bag)
    _substrate(design, bag, specs)
    _overlaps(design, bag, specs)
    _mount_plausibility(design, bag, specs)
    for beam in design.beams:
        ratio = beam.length / beam.section.min_feature
        if not SLENDERNESS[0] <= ratio <= SLENDERNESS[1]:
            bag.error("E408", f"beam `{beam.name}` has slenderness L/d = {ratio:.3g}, outside {SLENDERNESS[0]:g}..{SLENDERNESS[1]:g}",
                      beam.span, "beam theory (paper Eq. 1) needs a slender beam; change its length or section")
    for c in design.capsules:
        if design.mount_of(c.name) is None and not any(j.kind == "link" and c.name in (j.a, j.b) for j in design.joints):
            bag.warning("W401", f"capsule `{c.name}` is not attached to anything (mount, fix or link)", c.span,
                        f"e.g. `mount {c.name} on BEAM.tip`, `fix {c.name}`, or `link {c.name} to OTHER with TRUSS` "
                        "to carry it with a capsule that is attached")


def _feature(bag, size: float, axial: bool, what: str, span) -> None:
    limit = PRINT_AXIAL if axial else PRINT_LATERAL
    if size < limit:
        bag.error("E407", f"{what} is {size * 1e6:.3g} um, below the printable resolution ({limit * 1e6:.2g} um "
                  f"{'axial' if axial else 'lateral'}, paper Supplementary Note 1)", span)


def _axial(direction) -> bool:
    return abs(direction[2]) > 0.7


def _printability(design: M.Design, bag: DiagnosticBag) -> None:
    for c in design.capsules:
        _feature(bag, c.cavity.wall, False, f"wall of capsule `{c.name}`", c.span)
        for o in c.orifices:
            _feature(bag, 2 * o.radius, False, f"orifice `{c.name}.{o.name}` diameter", o.span)
    for b in design.beams:
        # a vertical beam's section is printed laterally; a horizontal one has one axial dimension
        s = b.section
        if s.shape == "circle":
            _feature(bag, s.diameter, not _axial(b.axis), f"diameter of beam `{b.name}`", b.span)
        else:
            _feature(bag, s.width, False, f"width of beam `{b.name}`", b.span)
            _feature(bag, s.thickness, not _axial(b.axis), f"thickness of beam `{b.name}`", b.span)
    for l in design.latches:
        _feature(bag, l.width, False, f"width of latch `{l.name}`", l.span)
        _feature(bag, l.thickness, True, f"thickness of latch `{l.name}`", l.span)


def _inside_print_volume(design: M.Design, bag: DiagnosticBag) -> bool:
    """Every position within PRINT_VOLUME of the origin, every beam shorter than it (E414)."""
    ok = True
    points = ([(f"capsule `{c.name}`", c.center, c.span) for c in design.capsules]
              + [(f"beam `{b.name}`", p, b.span) for b in design.beams for p in (b.clamp, b.tip)]
              + [(f"latch `{l.name}`", l.anchor, l.span) for l in design.latches])
    reported = set()
    for b in design.beams:
        if b.length > PRINT_VOLUME:
            bag.error("E414", f"beam `{b.name}` is {b.length:.3g} m long, beyond any print volume ({PRINT_VOLUME:g} m)",
                      b.span, "check the units of its length")
            reported.add(f"beam `{b.name}`")
            ok = False
    for what, p, span in points:
        if max(abs(x) for x in p) > PRINT_VOLUME and what not in reported:
            reported.add(what)
            bag.error("E414", f"{what} is placed {max(abs(x) for x in p):.3g} m from the origin, "
                      f"outside any print volume ({PRINT_VOLUME:g} m)", span, "check the units of its position")
            ok = False
    return ok


def _substrate(design: M.Design, bag: DiagnosticBag, specs) -> None:
    down = (0.0, 0.0, -1.0)
    for c in design.capsules:
        spec = specs.get(c.name)
        low = c.center[2] - (spec.extent(down) if spec else 0.0)
        if low < -1e-12:
            bag.error("E404", f"capsule `{c.name}` reaches {(-low) * 1e6:.3g} um below the substrate (z = 0)", c.span,
                      "raise its centre or mount it higher")
    for b in design.beams:
        if min(b.clamp[2], b.tip[2]) < -1e-12:
            bag.error("E404", f"beam `{b.name}` goes below the substrate (z = 0)", b.span)
    for l in design.latches:
        if l.anchor[2] < -1e-12:
            bag.error("E404", f"latch `{l.name}` is below the substrate (z = 0)", l.span)


def _touching_orifices(a: M.Capsule, b: M.Capsule, bag: DiagnosticBag) -> None:
    """Orifices of two capsules closer than the printable gap: the two bubbles are one (and the
    bubble-bubble force of paper Eq. 3, ~1/d^2, has no finite value)."""
    for oa in a.orifices:
        for ob in b.orifices:
            d = G.norm(G.sub(ob.center, oa.center))
            if d < PRINT_LATERAL:
                bag.error("E403", f"orifices `{a.name}.{oa.name}` and `{b.name}.{ob.name}` are {d * 1e6:.3g} um apart, "
                          f"below the printable gap ({PRINT_LATERAL * 1e6:.2g} um): their bubbles merge", b.span,
                          "move the capsules apart")


def _cell_index(q: float) -> int:
    """Grid cell of a coordinate in cell units; absurd (overflowing) coordinates share an end cell."""
    return int(math.floor(q)) if math.isfinite(q) else (2**1100 if q > 0 else -2**1100)


def _overlaps(design: M.Design, bag: DiagnosticBag, specs) -> None:
    """Pairs whose outer bodies overlap along their line of centres; a spatial grid keeps it linear."""
    caps = [c for c in design.capsules if c.name in specs]
    if len(caps) < 2:
        return
    bound = {c.name: specs[c.name].bounding_radius() for c in caps}
    cell = 2 * max(bound.values())
    grid: dict[tuple[int, int, int], list[int]] = {}
    for i, c in enumerate(caps):
        grid.setdefault(tuple(_cell_index(x / cell) for x in c.center), []).append(i)
    for key, members in grid.items():
        near = [j for dx in (-1, 0, 1) for dy in (-1, 0, 1) for dz in (-1, 0, 1)
                for j in grid.get((key[0] + dx, key[1] + dy, key[2] + dz), ())]
        for i in members:
            a = caps[i]
            for j in near:
                if j <= i:
                    continue
                b = caps[j]
                d = G.sub(b.center, a.center)
                dist = G.norm(d)
                if dist >= bound[a.name] + bound[b.name]:
                    continue
                _touching_orifices(a, b, bag)
                if dist == 0:
                    bag.error("E403", f"capsules `{a.name}` and `{b.name}` have the same centre", b.span)
                    continue
                u = G.scale(d, 1 / dist)
                reach = specs[a.name].extent(u) + specs[b.name].extent(G.scale(u, -1))
                if reach - dist > OVERLAP_TOL:
                    bag.error("E403", f"capsules `{a.name}` and `{b.name}` overlap by {(reach - dist) * 1e6:.3g} um", b.span,
                              "move them apart")


def _mount_plausibility(design: M.Design, bag: DiagnosticBag, specs) -> None:
    for j in design.joints:
        if j.kind != "mount" or j.target_kind != "beam":
            continue
        c = design.capsule(j.capsule)
        beam = design.beam(j.target)
        spec = specs.get(c.name)
        if spec is None:
            continue
        d = G.norm(G.sub(c.center, beam.tip))
        reach = spec.extent(G.scale(G.sub(c.center, beam.tip), 1 / d)) if d > 0 else 0.0
        if d > reach + 1e-6:
            bag.error("E405", f"capsule `{c.name}` is {d * 1e6:.3g} um from `{beam.name}.tip`, beyond its own size", j.span,
                      "omit the capsule's `center` to seat it on the tip")


def check_programs(design: M.Design, bag: DiagnosticBag) -> None:
    tr = design.transducer
    for p in design.programs:
        for st in p.steps:
            freqs, volts = step_tones(st)
            if tr is not None:
                lo, hi = tr.band
                for f in freqs:
                    if not lo * (1 - 1e-9) <= f <= hi * (1 + 1e-9):
                        bag.error("E501", f"{f / 1e3:.4g} kHz is outside the band of transducer `{tr.name}` "
                                  f"({lo / 1e3:.4g}..{hi / 1e3:.4g} kHz)", st.span, "choose a frequency inside the band")
                        break
                if volts is not None and volts > tr.max_voltage * (1 + 1e-9):
                    bag.error("E502", f"{volts:.3g} V exceeds the maximum {tr.max_voltage:.3g} V of transducer `{tr.name}`",
                              st.span, "lower the amplitude or its limit")
            _check_chain(design, st, freqs, volts, bag)


def _check_chain(design: M.Design, st, freqs, volts, bag: DiagnosticBag) -> None:
    """A step the declared generator and amplifier cannot deliver: E502 (a peak beyond the amplifier's
    output, or beyond what the generator can feed it), E501 (a tone beyond their bandwidth)."""
    gen, amp = design.generator, design.amplifier
    gain = amp.gain if amp is not None else 1.0
    if amp is not None and volts is not None and volts > amp.max_voltage * (1 + 1e-9):
        bag.error("E502", f"{volts:.3g} V exceeds the {amp.max_voltage:.3g} V output of amplifier `{amp.name}`",
                  st.span, "lower the amplitude or its limit, or declare a stronger amplifier")
    elif gen is not None and volts is not None and volts / gain > gen.max_voltage * (1 + 1e-9):
        via = f" through amplifier `{amp.name}` (gain {gain:g})" if amp is not None else ""
        bag.error("E502", f"{volts:.3g} V needs {volts / gain:.3g} V from generator `{gen.name}`{via}: beyond its "
                  f"{gen.max_voltage:.3g} V output", st.span, "lower the amplitude, or declare an amplifier of more gain")
    limits = [(amp.bandwidth, f"the {amp.bandwidth / 1e3:.4g} kHz bandwidth of amplifier `{amp.name}`")
              if amp is not None and amp.bandwidth else None,
              (gen.max_frequency, f"the {gen.max_frequency / 1e3:.4g} kHz of generator `{gen.name}`")
              if gen is not None and gen.max_frequency else None]
    for lim in limits:
        if lim is None:
            continue
        f = max(freqs, default=0.0)
        if f > lim[0] * (1 + 1e-9):
            bag.error("E501", f"{f / 1e3:.4g} kHz is beyond {lim[1]}", st.span, "choose a lower frequency")
            break


def step_tones(st) -> tuple[list[float], float | None]:
    if st.kind == "drive":
        return [t.frequency for t in st.drive.tones], sum(t.amplitude for t in st.drive.tones)
    if st.kind == "sweep":
        return [st.f_start, st.f_stop], st.amplitude
    if st.kind in ("follow", "switch", "hold"):
        return list(st.tones), st.limits.max_voltage
    return [], None
