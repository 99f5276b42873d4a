"""Design instances reduced to what the fit's forward model needs: units of one or two actuators and their supports.

One :class:`Instance` per override set (``set:NAME`` columns).  A design is cut into independent
**units** (docs/fit.md): two capsules named together in a ``gap`` observe form a *pair* (paper
Eq. (3): Bjerknes attraction, thrust and the partner's jet drag); every other carried capsule is a
*single* actuator.  A unit's sides are the capsules and what carries them:

* ``beam`` -- a cantilever (paper Eq. (1), elastica with ``large_deflection``);
* ``spring`` -- a linear flexure (paper Fig. 5c), deflection P/k along its axis;
* ``fixed`` -- a capsule fixed to the substrate (it pushes its partner, it does not move);
* ``latch`` -- a bistable inclined-beam latch (paper Fig. 6, :mod:`acl.physics.latch`), tabulated.

Each row belongs to the unit of its observable, so one data set can mix experiments (a pair and an
isolated calibration cantilever of the same design) that share every coefficient.  Capsules of
different units are taken not to interact (declare a ``gap`` observe between two capsules to
couple them).  Three or more interacting capsules, bodies (several orifices, trussed capsules) alone
or interacting, and latches among interacting capsules are *groups* (:class:`Network`, solved by
:mod:`acl.fit.group` with the analysis' force terms); a body on two supports, a direction a body
cannot move in, capsules floating on springs are diagnostics (E810), not guesses.  Frequency
responses come from :mod:`acl.analysis.acoustics` (thrust and Bjerknes coefficient per V^2 at each
tone frequency, with the design's transducer table).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from acl.diagnostics import DiagnosticError, error

LAW_CODES = {"beam": 0, "spring": 1, "fixed": 2, "latch": 3}


@dataclass
class Side:
    capsule: str
    element: str                 # beam / spring / latch name ("" when fixed)
    law: str                     # "beam" | "spring" | "fixed" | "latch"
    L: float = 1.0               # beam: flexible length
    l: float = 0.0               # beam: rigid half-actuator length
    EI: float = 1.0              # beam: bending stiffness
    E: float = 0.0               # Young's modulus (beam, latch)
    compliance: float = 0.0      # spring: 1/k
    latch: tuple = ()            # latch: (angle, length, width, thickness, E)
    height: float = 0.0          # orifice centre above the substrate
    u: np.ndarray = field(default_factory=lambda: np.zeros(3))   # direction of positive deflection
    proj: float = 1.0            # share of the load along u
    rest: np.ndarray = field(default_factory=lambda: np.zeros(3))
    mode: tuple = (1e5, 10.0)    # natural frequency (Hz) and Q of the first mode
    bubble: tuple = (0.0, 0.0)   # gas volume (m^3), orifice radius (m)
    members: tuple = ()          # group node: every capsule moving with it (trusses)
    basis: np.ndarray = None     # group node: 3 x k directions it can move along (k = 0, 1 or 2)
    springs: tuple = ()          # group node: (stiffness, unit axis) of each spring tying it to a fixed point


@dataclass
class Unit:
    kind: str                    # "single" | "pair"
    sides: tuple                 # 1 or 2 Side
    d0: float = float("nan")     # pair: rest distance between the orifices
    net: object = None           # group: the Network of its bodies, capsules and orifices

    @property
    def capsules(self):
        return tuple(s.capsule for s in self.sides)


@dataclass
class Instance:
    design: object
    units: dict                            # observable name -> Unit
    medium: tuple                          # (density, surface tension, ambient pressure, polytropic index)
    _tau: dict = field(default_factory=dict)
    declared: dict = field(default_factory=dict)   # the design's declared effects in the fit's coordinates

    @property
    def kind(self):
        kinds = {u.kind for u in self.units.values()}
        return kinds.pop() if len(kinds) == 1 else "mixed"

    def unit(self, name) -> Unit:
        return self.units[name]

    def output_map(self, obs) -> tuple[float, float, float]:
        """(base, scale on deflection of side 0, scale on side 1) of observable ``obs``."""
        unit = self.units[obs.name]
        if obs.kind == "state":              # predicted from the latch's push (acl.fit.forward), not a position
            return 0.0, 0.0, 0.0
        if obs.kind == "gap":
            return unit.d0, -1.0, -1.0
        k = next(i for i, s in enumerate(unit.sides) if obs.target in (s.capsule, s.element))
        s = [0.0, 0.0]
        side = unit.sides[k]
        if obs.kind == "displacement":
            axis = np.asarray(obs.axis, float)
            s[k] = float(side.u @ (axis / np.linalg.norm(axis)))
            return 0.0, s[0], s[1]
        comp = "xyz".index(obs.component)
        s[k] = float(side.u[comp])
        return float(side.rest[comp]), s[0], s[1]


def _unsupported(obs, why, hint=None):
    return DiagnosticError([error("E810", f"observable `{obs.name}` cannot be predicted by the fit model: {why}",
                                  obs.span, hint)])


def _carrier(design, cap, springs_ok=False):
    """(law, element) carrying capsule ``cap``: beam / spring / latch mount, fixed, or (None, why).  ``springs_ok``:
    spring links are the group's business (:func:`spring_links`), not a reason to refuse."""
    for j in design.joints:
        if j.kind == "link" and j.element_kind == "spring" and cap in (j.a, j.b) and not springs_ok:
            return None, f"capsule `{cap}` is linked by a spring (`{j.element}`)"
    for j in design.joints:
        if j.kind == "mount" and j.capsule == cap:
            return j.target_kind, j.target
        if j.kind == "fix" and j.capsule == cap:
            return "fixed", ""
    for j in design.joints:
        if j.kind == "link" and cap in (j.a, j.b):
            return None, f"capsule `{cap}` is linked by a {j.element_kind} (`{j.element}`)"
    return None, f"capsule `{cap}` is free (no mount, fix or link)"


def rigid_body(design, cap) -> tuple:
    """(members, carrier capsule, basis 3 x k) of the rigid body that holds capsule ``cap``.

    Trusses (paper Fig. 5a, Fig. 6e) as in :func:`acl.analysis.mechanics.build_mechanism`: a truss
    that carries an unsupported capsule makes one rigid body with its partner (both move together);
    a truss between a supported capsule and a fixed point (a fixed capsule, an anchor) is a bar whose
    length is kept, which removes its direction from the body's motion; a truss between two moving
    supports couples them (E810: not in the fit model).  ``basis`` spans the body's allowed motion
    (a beam: the plane across it; a spring or latch: its axis; fixed: empty)."""
    from acl.analysis.mechanics import build_mechanism

    mech = build_mechanism(design)            # its joint errors are the analysis' own located diagnostics
    g = mech.member_group[cap]
    members = tuple(mech.groups[g])
    held = [m for m in members if design.mount_of(m) is not None]
    if len(held) > 1:
        if any(design.mount_of(m).kind == "fix" for m in held):       # tied to a fixed capsule: it cannot move
            return members, held[0], np.zeros((3, 0))
        raise DiagnosticError([error("E810", f"capsules {', '.join(f'`{m}`' for m in held)} are held by two supports and "
                                     "tied together: a body on two supports is not in the fit model", design.capsule(cap).span,
                                     "observe each support's body alone, or tie it to a fixed point")])
    if not held:
        raise DiagnosticError([error("E810", f"capsule `{cap}` is held by no mount or fix (it floats on springs); "
                                     "the fit model needs a beam, spring or latch carrying it", design.capsule(cap).span)])
    A, o = mech.bases[g], mech.offsets[g]
    k = A.shape[1]
    if k == 0:
        return members, held[0], A
    Zg = mech.Z[o:o + k]                       # bar constraints (paper Fig. 5a trusses) on this body's coordinates
    cols = np.flatnonzero(np.abs(Zg).max(axis=0) > 1e-12)
    if cols.size:
        others = np.abs(np.delete(mech.Z[:, cols], np.arange(o, o + k), axis=0))
        if others.size and others.max() > 1e-9:
            link = next((j for j in design.joints if j.kind == "link" and j.element_kind == "truss"
                         and (j.a in members or j.b in members)), None)
            raise DiagnosticError([error("E810", f"a truss ties the body of `{cap}` to another moving support: coupled "
                                         "supports are not in the fit model",
                                         link.span if link is not None else design.capsule(cap).span,
                                         "observe bodies whose trusses end on fixed points")])
    B_ = A @ Zg[:, cols] if cols.size else np.zeros((3, 0))
    if B_.shape[1]:
        u, sv, _ = np.linalg.svd(B_, full_matrices=False)
        B_ = u[:, sv > 1e-9]
    return members, held[0], B_


def _side(design, cap_name, direction) -> Side:
    """Side for capsule ``cap_name`` whose load acts along unit vector ``direction`` (positive = deflection)."""
    from acl.analysis.acoustics import capsule_modes

    cap = design.capsule(cap_name)
    law, element = _carrier(design, cap_name)
    if law is None:
        raise DiagnosticError([error("E810", f"{element}: the fit model handles capsules on cantilevers, springs "
                                     "and latches, or fixed (trussed arms and free capsules are not in the fit "
                                     "model, docs/fit.md)", cap.span)])
    if len(cap.orifices) != 1:
        raise DiagnosticError([error("E810", f"capsule `{cap.name}` has {len(cap.orifices)} orifices; in a pair or a "
                                     "group the fit model handles single-orifice actuators (a multi-orifice capsule "
                                     "is fitted alone, in the plane: docs/fit.md)", cap.span)])
    tie = next((j for j in design.joints if j.kind == "link" and j.element_kind == "truss" and cap_name in (j.a, j.b)),
               None)
    if tie is not None:
        raise DiagnosticError([error("E810", f"capsule `{cap_name}` is tied by the truss `{tie.element}`; in a pair or a "
                                     "group the fit model handles capsules on their own supports (a trussed body is "
                                     "fitted alone: docs/fit.md)", tie.span)])
    direction = np.asarray(direction, float)
    m = capsule_modes(design, cap)[0]
    s = Side(cap.name, element, law, height=float(cap.orifices[0].center[2]), rest=np.asarray(cap.center, float),
             mode=(m.frequency_hz, m.q), bubble=(float(cap.cavity.volume), float(cap.orifices[0].radius)))
    if law == "fixed":
        s.u, s.proj = direction, 0.0
        return s
    if law == "beam":
        b = design.beam(element)
        ax = np.asarray(b.axis, float) / np.linalg.norm(b.axis)
        perp = direction - (direction @ ax) * ax
        s.L, s.l, s.EI, s.E = b.length, b.rigid_length, b.bending_stiffness, b.youngs_modulus
    elif law == "spring":
        sp = design.spring(element)
        ax = np.asarray(sp.axis, float) / np.linalg.norm(sp.axis)
        perp = (direction @ ax) * ax
        s.compliance = 1.0 / sp.stiffness
    else:
        lt = design.latch(element)
        ax = np.asarray(lt.axis, float) / np.linalg.norm(lt.axis)
        perp = (direction @ ax) * ax
        from acl.analysis.mechanics import latch_geometry

        s.latch = tuple(float(x) for x in latch_geometry(lt))
        s.E = float(lt.youngs_modulus)
        if lt.state != "a":
            raise DiagnosticError([error("E810", f"latch `{lt.name}` rests in state b; the fit model starts latches "
                                         "in state a (as printed)", lt.span)])
    norm = float(np.linalg.norm(perp))
    if norm < 1e-9:
        raise DiagnosticError([error("E810", f"the force on `{cap.name}` is along its {law} `{element}`'s stiff "
                                     "direction: no motion the fit model can follow", cap.span)])
    s.u, s.proj = perp / norm, norm
    return s


def _needs_body(design, cap) -> bool:
    """A capsule the 1-D single-actuator law cannot follow: several orifices, or tied by a truss or a spring."""
    c = design.capsule(cap)
    return len(c.orifices) != 1 or any(j.kind == "link" and j.element_kind in ("truss", "spring") and cap in (j.a, j.b)
                                       for j in design.joints)


def spring_links(design, members) -> tuple:
    """((stiffness, unit axis), ...) of the springs linking the rigid body ``members`` to a fixed point (a fixed
    capsule or body, an anchor, ``ground``): each pulls the body back along its axis by k (n . x) n, as
    acl.analysis.mechanics does.  A spring to another moving body couples two supports (E810)."""
    names = {c.name for c in design.capsules}
    out = []
    for j in design.joints:
        if not (j.kind == "link" and j.element_kind == "spring") or not ({j.a, j.b} & set(members)):
            continue
        other = j.b if j.a in members else j.a
        if other in members:
            continue
        if other in names and rigid_body(design, other)[2].shape[1]:
            raise DiagnosticError([error("E810", f"the spring `{j.element}` links the body of `{other}` to another "
                                         "moving support: coupled supports are not in the fit model", j.span,
                                         "observe bodies whose springs end on fixed points")])
        sp = design.spring(j.element)
        a = np.asarray(sp.axis, float)
        out.append((float(sp.stiffness), a / np.linalg.norm(a)))
    return tuple(out)


def _needs_group(design, caps) -> bool:
    """Capsules a pair (paper Eq. (3), one orifice each on its own support) cannot follow: a body (several orifices,
    trussed) or a latch among them; they are solved as a group (acl.fit.group)."""
    return any(_needs_body(design, c) or _carrier(design, c)[0] == "latch" for c in caps)


def _check_direction(design, unit, obs) -> None:
    """E810 at ``obs`` when it measures a direction in which its capsule's node cannot move (the data cannot tell
    any coefficient: paper Fig. 5a with the trusses as bars holds each arm along the line of its load)."""
    if obs.kind not in ("displacement", "position"):
        return
    net = unit.net
    cap = _target_capsule(design, obs)
    node = unit.sides[int(net.cap_node[net.caps.index(cap)])]
    axis = (np.asarray(obs.axis, float) / np.linalg.norm(obs.axis) if obs.kind == "displacement"
            else np.eye(3)["xyz".index(obs.component)])
    if node.basis.shape[1] and np.any(np.abs(axis @ node.basis) > 1e-9):
        return
    why = ", ".join(j.element for j in design.joints if j.kind == "link" and j.element_kind == "truss"
                    and (j.a in node.members or j.b in node.members))
    raise _unsupported(obs, f"it measures a direction in which the body of `{cap}` cannot move (its support"
                       f"{' and the truss ' + why if why else ''} hold it there): the data cannot tell any coefficient",
                       "observe a direction the body moves in")


MODELS = ("coupled", "eq3")     # the force model of a simple pair (`acl fit --model`): the analysis' own
                                # (default) or paper Eq. (3), a declared reduced model


def build_instance(design, model: str = "coupled", coupled: bool = False) -> Instance:
    """Cut a resolved design into units, one per observable (raises E810 for unsupported mechanisms).

    ``model``: how a simple pair (two single-orifice capsules on their own supports) is modelled: ``eq3`` paper
    Eq. (3) (a ``pair`` unit, acl.fit.forward), ``coupled`` the analysis' force model (a ``group`` unit,
    acl.fit.group: per-orifice thrust, Bjerknes force between the orifices, jet drag, coupled volumes).

    When any observable needs the group model (three or more interacting capsules, a body, a latch among
    interacting capsules, a pair under ``model="coupled"``), the group is the **whole design**: every capsule of it,
    so capsules the analysis couples (a calibration beam next to a group) interact in the fit too (the same
    equilibrium as acl.analysis.mechanics.equilibrium).  ``coupled``: route every design so, lone actuators
    included."""
    from acl.analysis.acoustics import medium_constants

    # the design's declared effects (a calibration, a calibrated design fitted again) act in the fit's base model as
    # fixed effects of the fit (acl.fit.effects.declared_effects; a fitted effect of the same id replaces them), so
    # they are taken off the design here (applied once, by the fit)
    from acl.fit.effects import declared_effects

    declared = declared_effects(design)
    design = design.model_copy(update={"effects": ()}) if design.effects else design
    if not design.observes:
        raise DiagnosticError([error("E810", "the design declares no `observe`: nothing to fit",
                                     design.capsules[0].span if design.capsules else None)])
    partners: dict[str, set] = {}
    for o in design.observes:
        if o.kind == "gap":
            a, b = o.a.split(".")[0], o.b.split(".")[0]
            if a != b:
                partners.setdefault(a, set()).add(b)
                partners.setdefault(b, set()).add(a)
    units_by_caps: dict = {}
    comp: dict = {}                       # capsule -> its connected component of interacting capsules
    for c in partners:
        if c in comp:
            continue
        seen, todo = [], [c]
        while todo:
            x = todo.pop()
            if x not in seen:
                seen.append(x)
                todo.extend(sorted(partners[x]))
        members = tuple(n.name for n in design.capsules if n.name in seen)
        for x in members:
            comp[x] = members

    def group_unit(caps, obs):
        if caps not in units_by_caps:
            units_by_caps[caps] = _group(design, caps, obs)
        return units_by_caps[caps]

    def pair_unit(a, b, obs):
        if len(comp.get(a, ())) > 2 or _needs_group(design, comp.get(a, (a, b))) or model == "coupled":
            return group_unit(comp[a], obs)
        key = tuple(sorted((a, b)))
        if key not in units_by_caps:
            for c in (a, b):
                if len(partners.get(c, ())) > 1:
                    raise _unsupported(obs, f"capsule `{c}` interacts with {len(partners[c])} others (a group); the "
                                       "fit model handles pairs (paper Eq. (3))", "observe a pair and lone actuators")
            ca, cb = design.capsule(a), design.capsule(b)
            pa = np.asarray(ca.orifices[0].center if ca.orifices else ca.center, float)
            pb = np.asarray(cb.orifices[0].center if cb.orifices else cb.center, float)
            line = pb - pa
            d0 = float(np.linalg.norm(line))
            if d0 <= 0:
                raise DiagnosticError([error("E810", "the two actuators' orifices coincide", cb.span)])
            ua = line / d0
            sa, sb = _side(design, a, ua), _side(design, b, -ua)
            if "latch" in (sa.law, sb.law):
                raise _unsupported(obs, "a latch in a pair is not in the fit model", "observe the latch alone")
            if sa.law == "fixed" and sb.law == "fixed":
                raise _unsupported(obs, "both capsules of the pair are fixed: nothing moves")
            units_by_caps[key] = Unit("pair", (sa, sb), d0)
        return units_by_caps[key]

    def needs_group(o) -> bool:
        if o.kind == "gap":
            a, b = o.a.split(".")[0], o.b.split(".")[0]
            return a != b and (len(comp.get(a, ())) > 2 or _needs_group(design, comp.get(a, (a, b))))
        cap = _target_capsule(design, o)
        if cap not in comp and _needs_body(design, cap):
            members = rigid_body(design, cap)[0]
            cap = next((m for m in members if m in comp), cap)
            if cap not in comp:
                return True
        return len(comp.get(cap, ())) > 2 or (cap in comp and _needs_group(design, comp[cap]))

    units = {}
    if coupled or any(needs_group(o) for o in design.observes) or (model == "coupled" and partners):
        # one physics: every capsule of the design in one group (the analysis couples them all through the liquid)
        whole = tuple(c.name for c in design.capsules)
        for o in design.observes:
            units[o.name] = group_unit(whole, o)
            _check_direction(design, units[o.name], o)
        # neighbour_drag (the paper's plateau, Fig. 5b: drag of a close neighbour) acts on the nodes with a neighbour:
        # capsules named together in a `gap` observe, or tied by a truss or spring to another node; not on a
        # calibration beam 400 um away (as when it was a lone actuator)
        net = units[design.observes[0].name].net
        node = dict(zip(net.caps, net.cap_node))
        near = set(comp)
        for j in design.joints:
            if j.kind == "link" and j.element_kind in ("truss", "spring") and node.get(j.a) != node.get(j.b):
                near |= {j.a, j.b}
        net.neighboured = np.array([any(node.get(c) == i and c in near for c in net.caps)
                                    for i in range(int(net.cap_node.max()) + 1)], bool)
        med = medium_constants(design)
        return Instance(design=design, declared=declared, units=units,
                        medium=(med.density, med.surface_tension, med.ambient_pressure, med.polytropic_index))
    for o in design.observes:
        if o.kind == "gap":
            a, b = o.a.split(".")[0], o.b.split(".")[0]
            units[o.name] = pair_unit(a, b, o)
            continue
        cap = _target_capsule(design, o)
        if cap not in comp and _needs_body(design, cap):
            # a member of a trussed body whose other member interacts: that group
            members = rigid_body(design, cap)[0]
            cap = next((m for m in members if m in comp), cap)
        if len(comp.get(cap, ())) > 2 or (cap in comp and (_needs_group(design, comp[cap]) or model == "coupled")):
            units[o.name] = group_unit(comp[cap], o)
            _check_direction(design, units[o.name], o)
            continue
        if cap in partners:
            units[o.name] = pair_unit(cap, next(iter(partners[cap])), o)
            continue
        if _needs_body(design, cap):
            # a body alone (several orifices, or trussed): a group of one node (acl.fit.group)
            units[o.name] = group_unit((cap,), o)
            _check_direction(design, units[o.name], o)
            continue
        if (cap,) not in units_by_caps:
            c = design.capsule(cap)
            if not c.orifices:
                raise _unsupported(o, f"capsule `{cap}` has no orifice")
            t = -np.asarray(c.orifices[0].normal, float)
            units_by_caps[(cap,)] = Unit("single", (_side(design, cap, t / np.linalg.norm(t)),))
        units[o.name] = units_by_caps[(cap,)]
    med = medium_constants(design)
    return Instance(design=design, declared=declared, units=units,
                    medium=(med.density, med.surface_tension, med.ambient_pressure, med.polytropic_index))


@dataclass
class Network:
    """The capsules and orifices of a group (acl.fit.group): every capsule rides one node (a rigid body on one
    support, :func:`rigid_body`), every orifice belongs to one capsule; arrays in this order."""

    caps: tuple                  # C capsule names (design order)
    cap_node: np.ndarray         # (C,) node (Unit.sides index) carrying each capsule
    rest: np.ndarray             # (C, 3) capsule centres at rest
    outer: np.ndarray            # (C,) equal-volume sphere + wall radius (the body a jet drags, acl.analysis.acoustics)
    labels: tuple                # n orifice labels "capsule.orifice"
    orif_cap: np.ndarray         # (n,) capsule index of each orifice
    offsets: np.ndarray          # (n, 3) orifice centre - capsule centre
    normals: np.ndarray          # (n, 3) outward unit normals (the jets)
    modes: np.ndarray            # (n, 2) natural frequency (Hz) and Q of the mode each orifice dominates
    bubbles: tuple               # per capsule: (gas volume, orifice radii, natural frequency of each orifice's mode)
    neighboured: np.ndarray = None   # (N,) bool: the node has a close neighbour (neighbour_drag acts); None: every node

    @property
    def points(self) -> np.ndarray:
        """(n, 3) orifice centres at rest."""
        return self.rest[self.orif_cap] + self.offsets


def orifice_modes(design, cap) -> list:
    """[(f_n, Q, mode index)] of each orifice of ``cap``: the fundamental the orifice dominates
    (acl.analysis.acoustics.capsule_modes; an orifice dominating none takes the mode it moves most in)."""
    from acl.analysis.acoustics import capsule_modes

    c = design.capsule(cap)
    ms = capsule_modes(design, c)
    out = []
    for o in c.orifices:
        k = next((i for i, m in enumerate(ms) if m.dominant_orifice == o.name), None)
        if k is None:
            k = int(np.argmax([m.shares.get(o.name, 0.0) for m in ms])) if ms else 0
        m = ms[k] if ms else None
        out.append((m.frequency_hz, m.q, k) if m else (1e5, 10.0, 0))
    return out


def _node(design, cap, obs) -> Side:
    """The node (rigid body on its support) carrying capsule ``cap`` in a group: a beam moves across its axis (less
    the directions trusses to fixed points hold), a spring along its axis, a latch along its axis from state a, a
    fixed capsule (or one tied to a fixed point in every direction) not at all."""
    members, held, basis = rigid_body(design, cap)
    law, element = _carrier(design, held, springs_ok=True)
    hc = design.capsule(held)
    if law is None:
        raise DiagnosticError([error("E810", f"{element}: in a group the fit model handles bodies on cantilevers, "
                                     "springs and latches, or fixed (docs/fit.md)", hc.span)])
    s = Side(held, element, law, height=float(hc.orifices[0].center[2] if hc.orifices else hc.center[2]),
             rest=np.asarray(hc.center, float), members=members, basis=basis)
    if basis.shape[1]:
        s.springs = spring_links(design, members)
    if basis.shape[1] == 0:
        s.law, s.element = "fixed", ""
    elif law == "beam":
        b = design.beam(element)
        s.L, s.l, s.EI, s.E = b.length, b.rigid_length, b.bending_stiffness, b.youngs_modulus
    elif law == "spring":
        s.compliance = 1.0 / design.spring(element).stiffness
    elif law == "latch":
        from acl.analysis.mechanics import latch_geometry

        lt = design.latch(element)
        if lt.state != "a":
            raise DiagnosticError([error("E810", f"latch `{lt.name}` rests in state b; the fit model starts latches "
                                         "in state a (as printed)", lt.span)])
        s.latch = tuple(float(x) for x in latch_geometry(lt))
        s.E = float(lt.youngs_modulus)
        a = np.asarray(lt.axis, float) / np.linalg.norm(lt.axis)
        s.basis = a[:, None]
    s.u = s.basis[:, 0] if s.basis.shape[1] else np.zeros(3)
    return s


def _group(design, caps, obs) -> Unit:
    """A group: the capsules named together in ``gap`` observes (with every capsule their rigid bodies carry), or a
    body moving alone; each node on its own support.  Forces per orifice as in acl.analysis.acoustics.force_model:
    thrust along -n, secondary Bjerknes force between every two orifices of different capsules (paper Eq. (3)),
    the Schlichting jet of every orifice dragging every other capsule (acl.physics.forces.jet_drag)."""
    from acl.analysis.rows import outer_radius

    caps = list(caps)
    for name in caps:        # a truss's other end interacts with the body it holds (paper Fig. 5a bars): include it
        for j in design.joints:
            if j.kind == "link" and j.element_kind == "truss" and name in (j.a, j.b):
                other = j.b if j.a == name else j.a
                if other not in caps and any(c.name == other for c in design.capsules):
                    caps.append(other)
    nodes, node_of = [], {}
    for name in caps:
        if name in node_of:
            continue
        s = _node(design, name, obs)
        for m in s.members:
            node_of[m] = len(nodes)
        nodes.append(s)
    if all(s.law == "fixed" for s in nodes):
        if len(nodes) == 1:
            raise _unsupported(obs, f"the body of `{caps[0]}` ({', '.join(nodes[0].members)}) cannot move: it is fixed "
                               "or held by trusses in every direction its support allows", "observe a body that can move")
        raise _unsupported(obs, "every capsule of the group is fixed: nothing moves")
    names = tuple(c.name for c in design.capsules if c.name in node_of)
    labels, orif_cap, offs, nrm, modes, bubbles = [], [], [], [], [], []
    for ci, name in enumerate(names):
        c = design.capsule(name)
        om = orifice_modes(design, name) if c.orifices else []
        for o, (fn, q, _) in zip(c.orifices, om):
            labels.append(f"{name}.{o.name}")
            orif_cap.append(ci)
            offs.append(np.subtract(o.center, c.center))
            n = np.asarray(o.normal, float)
            nrm.append(n / np.linalg.norm(n))
            modes.append((fn, q))
        bubbles.append((float(c.cavity.volume), tuple(float(o.radius) for o in c.orifices), tuple(fn for fn, *_ in om)))
    if not labels:
        raise _unsupported(obs, "no capsule of the group has an orifice: nothing pushes")
    net = Network(names, np.array([node_of[n] for n in names]), np.array([design.capsule(n).center for n in names], float),
                  np.array([outer_radius(design.capsule(n)) for n in names]), tuple(labels), np.array(orif_cap),
                  np.array(offs, float).reshape(-1, 3), np.array(nrm, float).reshape(-1, 3), np.array(modes, float),
                  tuple(bubbles))
    pts = net.points
    other = net.cap_node[net.orif_cap][:, None] != net.cap_node[net.orif_cap][None, :]
    dd = np.linalg.norm(pts[:, None] - pts[None], axis=-1)
    d0 = float(dd[other].min()) if other.any() else float("nan")
    return Unit("group", tuple(nodes), d0, net=net)


def orifice_forces_per_v2(inst, frequency: float) -> tuple:
    """(labels, thrust (n,) N/V^2, Bjerknes coefficient att d^2 (n, n) N m^2/V^2) of every orifice of the design at
    rest under one tone of 1 V at ``frequency``: the analysis' own force terms (acl.analysis.acoustics, coupled
    volumes, transducer table, declared thrust)."""
    key = ("o", float(frequency))
    if key not in inst._tau:
        from acl.analysis.acoustics import interface_labels
        from acl.analysis.rows import force_engine
        from acl.design.model import Drive, Tone

        eng = force_engine(inst.design, Drive(tones=(Tone(frequency=float(frequency), amplitude=1.0),)))
        _, _, thr, att = eng.rest_forces()
        pts = eng.lay.points(eng.lay.rest)
        d2 = ((pts[:, None] - pts[None]) ** 2).sum(axis=-1)
        inst._tau[key] = (interface_labels(inst.design), np.asarray(thr[0], float), np.asarray(att[0] * d2, float))
    return inst._tau[key]


def _target_capsule(design, obs) -> str:
    """The capsule whose motion a displacement / position observe follows (E810 if none)."""
    names = {c.name for c in design.capsules}
    if obs.target in names:
        return obs.target
    carried = [j.capsule for j in design.joints if j.kind == "mount" and j.target == obs.target]
    if len(carried) == 1:
        return carried[0]
    raise _unsupported(obs, f"`{obs.target}` is neither an actuator nor an element carrying exactly one",
                       "observe a capsule, or a beam / spring / latch carrying one capsule")


def thrust_per_v2(inst: Instance, frequency: float) -> dict:
    """{capsule: thrust magnitude (N/V^2)} at ``frequency`` (acl.analysis.acoustics, declared thrust applied)."""
    key = ("t", float(frequency))
    if key not in inst._tau:
        from acl.analysis.acoustics import thrust_vectors
        from acl.design.model import Drive, Tone

        tv = thrust_vectors(inst.design, Drive(tones=(Tone(frequency=float(frequency), amplitude=1.0),)))
        inst._tau[key] = {c: float(np.linalg.norm(v)) for c, v in tv.items()}
    return inst._tau[key]


def alpha_per_v2(inst: Instance, unit: Unit, frequency: float) -> float:
    """Bjerknes coefficient alpha(f) = attraction d^2 per V^2 (N m^2/V^2) of a pair unit (acl.analysis.acoustics)."""
    want = set(unit.capsules)
    key = ("a", float(frequency), tuple(sorted(want)))
    if key not in inst._tau:
        from acl.analysis.acoustics import pair_forces
        from acl.design.model import Drive, Tone

        pf = pair_forces(inst.design, Drive(tones=(Tone(frequency=float(frequency), amplitude=1.0),)))
        val = next((p.attraction * p.distance**2 for p in pf if {p.a, p.b} == want), 0.0)
        inst._tau[key] = float(val)
    return inst._tau[key]


def pair_alpha_per_v2(inst: Instance, a: str, b: str, frequency: float) -> float:
    """Bjerknes coefficient alpha(f) (N m^2/V^2) of capsules ``a`` and ``b`` (acl.analysis.acoustics.pair_forces)."""
    key = ("a", float(frequency), tuple(sorted((a, b))))
    if key not in inst._tau:
        from acl.analysis.acoustics import pair_forces
        from acl.design.model import Drive, Tone

        pf = pair_forces(inst.design, Drive(tones=(Tone(frequency=float(frequency), amplitude=1.0),)))
        for p in pf:
            inst._tau[("a", float(frequency), tuple(sorted((p.a, p.b))))] = float(p.attraction * p.distance**2)
    return inst._tau.get(key, 0.0)


def reference_pair(inst: Instance, unit: Unit) -> tuple:
    """The capsules of the reference pair of a pair or group unit: the pair, or the first gap observed in the group."""
    if unit.kind == "pair":
        return unit.capsules
    caps = unit.net.caps if unit.net is not None else unit.capsules
    for o in inst.design.observes:
        if o.kind == "gap":
            a, b = o.a.split(".")[0], o.b.split(".")[0]
            if a in caps and b in caps:
                return a, b
    if unit.net is not None:       # the first two capsules on different nodes (a body alone has none: no pair)
        node = dict(zip(unit.net.caps, unit.net.cap_node))
        return next(((a, b) for i, a in enumerate(caps) for b in caps[i + 1:] if node[a] != node[b]), ())
    return unit.capsules[:2]


def reference_unit(inst: Instance, kind: str | None = None) -> Unit | None:
    """The first unit (in observe order) of ``kind`` (any kind if None)."""
    for u in inst.units.values():
        if kind is None or u.kind == kind:
            return u
    return None
