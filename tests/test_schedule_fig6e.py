"""Paper Fig. 6e through the real acoustics: a latch with an 85 kHz and a 170 kHz capsule."""
import numpy as np
import pytest

import acl
from acl.diagnostics import DiagnosticError
from acl.schedule.compile import CompileOptions, compile_program
from acl.schedule.gains import latch_forces

FIG6E = """\
import stdlib.capsules
import stdlib.materials
import stdlib.media
import stdlib.transducers

use medium media.pbs
use transducer transducers.contact_piezo

latch gate {
  angle = 45 deg
  length = 60 um
  width = 3 um
  thickness = 10 um
  material = materials.tpeta
  at = (0 um, 0 um, 20 um)
  axis = +x
}
capsule fwd like capsules.design2 {
  center = (0 um, -40 um, 40 um)
  orifice jet { radius = 13 um, normal = -x }
}
capsule back like capsules.design3 {
  center = (0 um, 40 um, 40 um)
}
truss bar { }
mount fwd on gate.shuttle
link back to fwd with bar

program toggle {
  switch gate to b, using [85 kHz, 125 kHz, 170 kHz]
  switch gate to a, using [85 kHz, 125 kHz, 170 kHz]
}
"""
TONES = [85e3, 125e3, 170e3]


@pytest.fixture(scope="module")
def design():
    return acl.loads(FIG6E, filename="fig6e.acl")


def test_the_85_khz_capsule_pushes_towards_b_and_the_trussed_170_khz_one_back(design):
    forces, to_b, to_a = latch_forces(design, TONES)
    assert forces[0, 0] > 0 and forces[0, 2] < 0
    assert to_b[0] > 0 and to_a[0] > 0


def test_with_switching_forces_within_reach_the_toggle_uses_85_then_170_khz(design):
    def reachable(d, freqs):
        forces, _, _ = latch_forces(d, freqs)
        return forces, np.array([2e-9]), np.array([2e-10])      # thresholds a soft latch would have

    s = compile_program(design, "toggle", CompileOptions(latch_provider=reachable, allow_nonlinear=True))
    assert [t.frequency_hz for t in s.segments[0].tones] == [85e3]
    assert [t.frequency_hz for t in s.segments[1].tones] == [170e3]


def test_the_printed_latch_is_too_stiff_for_20_v_and_the_diagnostic_says_so(design):
    with pytest.raises(DiagnosticError) as exc:
        compile_program(design, "toggle")
    d = exc.value.diagnostics[0]
    assert d.code == "E-SCHED-INFEASIBLE" and "amplitude limits" in d.message
    assert d.span.line == 30
