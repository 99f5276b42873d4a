"""The rule registry: every lint rule with its stable code, name, rationale and default severity.

A rule is a function ``check(ctx) -> iterable of Diagnostic`` registered with :func:`rule`.  Codes
never change meaning once released; a retired code is never reused.  Rule modules register on
import (:func:`load_rules` imports them all).  Thresholds a rule reads are declared in
:data:`THRESHOLDS` so that configuration can validate them.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Callable, Iterable

from acl.diagnostics import Diagnostic, Severity

CODE = re.compile(r"^ACL\d{3}$")


@dataclass(frozen=True)
class Rule:
    code: str
    name: str
    summary: str                   # one-line rationale
    severity: Severity
    family: str
    check: Callable[..., Iterable[Diagnostic]] | None
    thresholds: tuple[str, ...] = ()


@dataclass(frozen=True)
class Threshold:
    name: str
    default: float
    unit: str                      # SI unit of the value ("" dimensionless)
    doc: str


RULES: dict[str, Rule] = {}

THRESHOLDS: dict[str, Threshold] = {t.name: t for t in (
    Threshold("gain_ratio", 0.5, "", "ACL102: transducer gain at a resonance / best gain in the band, below which it is low"),
    Threshold("bandwidth_overlap", 1.0, "",
              "ACL103: modes overlap when |f1 - f2| < k (f1/Q1 + f2/Q2) / 2; this is k"),
    Threshold("crosstalk_ratio", 0.1, "",
              "ACL104: thrust of an unintended capsule relative to its own peak thrust, above which it is excited"),
    Threshold("force_significance", 0.05, "",
              "ACL202: Bjerknes force / the larger thrust of the pair below which its sign is not counted"),
    Threshold("snap_margin", 1.0, "", "ACL201: a pair snaps in when its gap < snap_margin x critical distance"),
    Threshold("latch_hold_factor", 1.2, "",
              "ACL301: a step endangers a latch when its force x this factor reaches the switching force"),
    Threshold("strain_limit", 0.05, "", "ACL401: largest elastic bending strain (5 % for TPETA)"),
    Threshold("eq1_tolerance", 0.05, "",
              "ACL402: departure of paper Eq. (1) from the elastica beyond which its deflection is not trusted"),
    Threshold("print_margin", 2.0, "", "ACL501: features below this multiple of the printer resolution are marginal"),
    Threshold("substrate_clearance", 50e-6, "m", "ACL502: smallest distance of a moving capsule from the substrate"),
    Threshold("orifice_min_radius", 2e-6, "m", "ACL503: smallest orifice radius holding a lasting bubble"),
    Threshold("cap_volume_ratio", 2.0, "",
              "ACL504: gas volume / volume of the hemispherical caps of all orifices, below which the bubble is unstable"),
    Threshold("linear_amplitude", 0.25, "",
              "ACL105: interface centre amplitude / orifice radius beyond which the linear bubble model fails"),
    Threshold("sweep_samples", 21, "", "ACL104/ACL202/...: frequencies sampled across a sweep or a program's range"),
)}


def rule(code: str, name: str, summary: str, severity: Severity = Severity.WARNING, family: str = "",
         thresholds: tuple[str, ...] = ()):
    """Register ``check`` under ``code``."""
    if not CODE.match(code):
        raise ValueError(f"bad rule code {code!r}")

    def deco(check):
        if code in RULES:
            raise ValueError(f"rule code {code} registered twice")
        for t in thresholds:
            if t not in THRESHOLDS:
                raise ValueError(f"{code}: unknown threshold {t}")
        RULES[code] = Rule(code, name, summary, severity, family or check.__module__.rsplit(".", 1)[-1],
                           check, tuple(thresholds))
        return check

    return deco


def meta_rule(code: str, name: str, summary: str, severity: Severity = Severity.WARNING) -> None:
    """Register a rule implemented by the runner itself (suppressions, internal failures)."""
    RULES[code] = Rule(code, name, summary, severity, "meta", None)


meta_rule("ACL900", "unused-suppression",
          "a `# acl: ignore[...]` comment that suppresses nothing hides future findings and misleads readers")
meta_rule("ACL901", "unjustified-suppression",
          "a suppression without a reason does not tell the reader why the finding is acceptable")
meta_rule("ACL999", "rule-failed", "a rule raised an error: its finding is unknown (please report it)",
          Severity.ERROR)

_LOADED = False


def load_rules() -> dict[str, Rule]:
    """Import every rule module (they register themselves) and return the registry."""
    global _LOADED
    if not _LOADED:
        from acl.lint.rules import acoustics, beams, declarations, fabrication, forces, latches  # noqa: F401

        _LOADED = True
    return RULES


def match_codes(pattern: str, rules: dict[str, Rule]) -> list[str]:
    """Codes matched by ``pattern``: an exact code, a prefix such as ``ACL1``, or ``ALL``."""
    p = pattern.strip().upper()
    if p == "ALL":
        return sorted(rules)
    return sorted(c for c in rules if c == p or (c.startswith(p) and len(p) >= 3 and p.startswith("ACL")))
