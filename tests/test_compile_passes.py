"""Issue 23 item 4: the compiler is a list of passes over one CompileState (acl.schedule.compile.PASSES), each in its
own module, imports flowing one way; and every example program's schedule keeps its structural invariants."""
from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest

import acl

ROOT = Path(__file__).resolve().parents[1]
SCHEDULE = ROOT / "acl" / "schedule"
# lowest first: a pass module imports only modules of a lower rank (the driver, compile.py, imports them all)
RANK = {"state": 0, "latch_state": 1, "reach": 2, "fades": 2, "validity": 2, "safety": 3, "verify": 2, "steps": 4,
        "switching": 4, "compile": 5}


def _schedule_imports(path: Path) -> set[str]:
    """The acl.schedule modules ``path`` imports, at the top or inside a function."""
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module:
            if node.module == "acl.schedule":
                out |= {a.name for a in node.names}
            elif node.module.startswith("acl.schedule."):
                out.add(node.module.split(".")[2])
        elif isinstance(node, ast.Import):
            out |= {a.name.split(".")[2] for a in node.names if a.name.startswith("acl.schedule.")}
    return out


def test_the_driver_runs_its_passes_in_order():
    from acl.schedule import compile as C

    assert [name for name, _ in C.PASSES] == ["numbers", "steps", "latch flips", "assemble", "coverage", "phases",
                                              "peaks", "slews", "validity", "pair scale"]
    assert set(C.STEP_PASSES) == {"drive", "sweep", "pause", "follow", "hold", "switch"}


@pytest.mark.parametrize("name", sorted(RANK))
def test_each_pass_module_imports_only_lower_ones_and_stays_small(name):
    path = SCHEDULE / f"{name}.py"
    assert len(path.read_text().splitlines()) < 500
    for other in _schedule_imports(path) & set(RANK):
        assert other != name and RANK[other] < RANK[name], f"{name} imports {other}"


def test_the_state_is_the_only_thing_passes_share():
    """No pass keeps module-level mutable state: every module-level assignment of a pass module is a constant."""
    for name in RANK:
        tree = ast.parse((SCHEDULE / f"{name}.py").read_text())
        for node in tree.body:
            if isinstance(node, (ast.Assign, ast.AnnAssign)):
                value = node.value
                assert not isinstance(value, (ast.List, ast.Dict, ast.Set, ast.ListComp, ast.DictComp)), \
                    f"{name}: module-level {ast.unparse(node)[:60]}"


def _invariants(design, sched, program):
    from acl.commands.rule import code_entries
    from acl.schedule.state import drive_limit

    segs = sched.segments
    assert segs[0].start_s == 0.0
    for a, b in zip(segs, segs[1:]):
        assert b.start_s == pytest.approx(a.end_s, rel=1e-12, abs=1e-15)
        assert b.step >= a.step                                     # steps in program order
    for g in sched.goals:
        mine = [s for s in segs if s.step == g.step]
        assert mine and g.start_s >= mine[0].start_s - 1e-12 and g.end_s <= mine[-1].end_s + 1e-12
    for s in segs:
        vmax, _ = drive_limit(design, getattr(program.steps[s.step], "limits", None), sched_opts())
        if s.peak_v is not None:
            assert s.peak_v <= min(vmax, sched.full_scale_v) * (1 + 1e-6)
    known = code_entries()
    lines = {st.span.line for st in program.steps}
    for w in sched.warnings:
        assert w.code in known, f"{w.code} is not explained by `acl rule`"
        assert w.span is not None and w.span.line in lines | {program.span.line}
        if w.severity.value != "info":      # an info note (N-PAIR-SCALE) is a diagnostic only, not a "warning:" line
            assert f"warning: {w.message}" in sched.notes


def sched_opts():
    from acl.schedule.compile import CompileOptions

    return CompileOptions()


def test_invariants_of_a_small_program():
    from acl.schedule.compile import compile_program

    d = acl.load(str(ROOT / "examples" / "fig2_stroke.acl"))
    s = compile_program(d, "ramp")
    _invariants(d, s, d.program("ramp"))
    assert {w.code for w in s.warnings} >= {"W-ACOUSTIC-STREAMING"}


@pytest.mark.studies
@pytest.mark.parametrize("name", sorted(p.stem for p in (ROOT / "examples").glob("*.acl")))
def test_every_example_program_keeps_the_schedule_invariants(name):
    # about a minute for all 35 programs (band 0)
    from acl.schedule.compile import compile_program

    d = acl.load(str(ROOT / "examples" / f"{name}.acl"))
    for p in d.programs:
        s = compile_program(d, p.name)
        _invariants(d, s, p)
        assert np.isfinite(s.max_voltage_v)
