"""Hold / cross a gap through the real mechanics (two facing capsules on cantilevers, as Fig. 4)."""
import pytest

import acl
from acl.schedule.compile import compile_program

PAIR = """\
import stdlib.capsules
import stdlib.beams
import stdlib.media
import stdlib.transducers

use medium media.pbs
use transducer transducers.contact_piezo

beam left like beams.cantilever50 { clamp = (0 um, 0 um, 0 um) }
beam right like beams.cantilever50 { clamp = (80 um, 0 um, 0 um) }
capsule a like capsules.design1 { }
capsule b like capsules.design1 { orifice jet { radius = 10 um, normal = -x } }
mount a on left.tip
mount b on right.tip

program squeeze {
  hold gap(a.jet, b.jet) above 20 um for 50 ms, using [125 kHz, 85 kHz]
  cross gap(a.jet, b.jet) for 50 ms, using [125 kHz, 85 kHz]
}
"""


@pytest.fixture(scope="module")
def schedule():
    return compile_program(acl.loads(PAIR, filename="pair.acl"), "squeeze")


def test_hold_stays_below_every_critical_voltage_by_the_margin(schedule):
    hold = schedule.goals[0]
    vcrit = dict(zip((125e3, 85e3), hold.details["critical_voltages_v"]))
    index = sum(t.amplitude_v ** 2 / vcrit[t.frequency_hz] ** 2 for t in schedule.segments[0].tones)
    assert 0 < index <= 1 / 1.2 ** 2 + 1e-6


def test_cross_drives_past_snap_in_with_the_cheapest_tone(schedule):
    cross = schedule.goals[1]
    vcrit = dict(zip((125e3, 85e3), cross.details["critical_voltages_v"]))
    (tone,) = schedule.segments[1].tones
    assert tone.frequency_hz == min(vcrit, key=vcrit.get)
    assert tone.amplitude_v == pytest.approx(1.2 * vcrit[tone.frequency_hz], rel=1e-4)   # margin on voltage
