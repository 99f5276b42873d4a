"""ACL5xx: what the printer and the physics of a trapped bubble can deliver.

Printer resolution: 0.2 um lateral, 0.3 um axial (paper Supplementary Note 1).  The checker
rejects features below it (E407); lint warns on features within ``print_margin`` of it.
"""
from __future__ import annotations

from acl.design.checks import PRINT_AXIAL, PRINT_LATERAL
from acl.design.geometry import half_extent
from acl.diagnostics import Severity
from acl.lint.context import Context, um
from acl.lint.registry import rule
from acl.physics.limits import interface_cap_volume


def _features(design):
    """(size m, axial?, what, span) of every printed feature, as the checker measures them."""
    for c in design.capsules:
        yield c.cavity.wall, False, f"wall of capsule `{c.name}`", c.span
        for o in c.orifices:
            yield 2 * o.radius, False, f"diameter of orifice `{c.name}.{o.name}`", o.span
    for b in design.beams:
        s = b.section
        vertical = abs(b.axis[2]) > 0.7
        if s.shape == "circle":
            yield s.diameter, not vertical, f"diameter of beam `{b.name}`", b.span
        else:
            yield s.width, False, f"width of beam `{b.name}`", b.span
            yield s.thickness, not vertical, f"thickness of beam `{b.name}`", b.span
    for l in design.latches:
        yield l.width, False, f"width of latch `{l.name}`", l.span
        yield l.thickness, True, f"thickness of latch `{l.name}`", l.span


@rule("ACL501", "marginal-feature",
      "features within a few voxels of the printer resolution print unreliably (Supplementary Note 1)",
      Severity.WARNING, "fabrication", ("print_margin",))
def marginal_feature(ctx: Context):
    k = ctx.threshold("print_margin")
    for size, axial, what, span in _features(ctx.design):
        res = PRINT_AXIAL if axial else PRINT_LATERAL
        if res <= size < k * res:
            yield ctx.finding("ACL501", f"{what} is {um(size)}, within {k:g}x the {'axial' if axial else 'lateral'} "
                              f"print resolution ({um(res)})", span,
                              notes=[f"threshold print_margin = {k:g}"],
                              hint="make the feature larger or check it on a test print")


@rule("ACL502", "substrate-proximity",
      "within ~50 um of the substrate the wall distorts bubble forces (paper Fig. 2a)",
      Severity.WARNING, "fabrication", ("substrate_clearance",))
def substrate_proximity(ctx: Context):
    limit = ctx.threshold("substrate_clearance")
    fixed = {j.capsule for j in ctx.design.joints if j.kind == "fix"}
    for c in ctx.design.capsules:
        if c.name in fixed:
            continue                     # a fixed capsule does not move: its own forces do not matter
        cav = c.cavity
        low = c.center[2] - half_extent(cav.shape, (0.0, 0.0, -1.0), cav.axis, cav.radius, cav.side, cav.height,
                                        cav.volume, cav.wall)
        if low < limit - 1e-9:
            yield ctx.finding("ACL502", f"capsule `{c.name}` is {um(low)} above the substrate, closer than {um(limit)}",
                              c.span, notes=["the paper raises its capsules 50 um on vertical beams (Fig. 2a) so "
                                             "that the wall does not distort the forces",
                                             f"threshold substrate_clearance = {um(limit)}"],
                              hint="raise the capsule (a taller beam or clamp)")


@rule("ACL503", "orifice-too-small",
      "a very small orifice has a high Laplace pressure: its gas dissolves and its mode is overdamped",
      Severity.WARNING, "fabrication", ("orifice_min_radius",))
def orifice_too_small(ctx: Context):
    rmin = ctx.threshold("orifice_min_radius")
    sigma = ctx.design.medium.surface_tension if ctx.design.medium else 0.0728
    for c in ctx.design.capsules:
        for o in c.orifices:
            if o.radius < rmin:
                yield ctx.finding("ACL503", f"orifice `{c.name}.{o.name}` has radius {um(o.radius)}, below {um(rmin)}",
                                  o.span, notes=[f"Laplace pressure 2 sigma / R = {2 * sigma / o.radius / 1e3:.3g} kPa",
                                                 f"threshold orifice_min_radius = {um(rmin)}"],
                                  hint="enlarge the orifice (paper designs use 7.5-15 um)")


@rule("ACL504", "orifice-too-large",
      "if the gas cannot fill every orifice's hemispherical cap with room to spare, the interface passes "
      "the hemisphere and the bubble escapes",
      Severity.WARNING, "fabrication", ("cap_volume_ratio",))
def orifice_too_large(ctx: Context):
    k = ctx.threshold("cap_volume_ratio")
    for c in ctx.design.capsules:
        caps = sum(float(interface_cap_volume(o.radius)) for o in c.orifices)
        if caps > 0 and c.cavity.volume < k * caps:
            biggest = max(c.orifices, key=lambda o: o.radius)
            yield ctx.finding("ACL504",
                f"capsule `{c.name}`: gas volume is {c.cavity.volume / caps:.2g}x the hemispherical caps of its "
                f"orifices, under {k:g}x", biggest.span, notes=[
                    f"V = {c.cavity.volume * 1e18:.4g} um^3; sum of 2/3 pi R^3 = {caps * 1e18:.4g} um^3",
                    f"threshold cap_volume_ratio = {k:g}"],
                hint="shrink the largest orifice or enlarge the cavity")
