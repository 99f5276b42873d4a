"""The drive chain in the language: `generator` and `amplifier` declarations (stdlib/bench.acl, the
paper's AFG-2225 and HVA200, datasheet values), checked by `acl check` and `acl compile`."""
from __future__ import annotations

import os

import pytest

import acl
from acl.cli import main

ROOT = os.path.join(os.path.dirname(__file__), "..")
HEAD = """\
import stdlib.capsules
import stdlib.beams
import stdlib.media
import stdlib.transducers
import stdlib.bench

use medium media.pbs
use transducer transducers.contact_piezo
"""
BODY = """
beam arm like beams.cantilever50 { clamp = (0 um, 0 um, 0 um) }
capsule module like capsules.prism3 { }
mount module on arm.tip

program tones {
  drive 85 kHz @ 3 V + 125 kHz @ 2 V for 20 ms
}
"""


def _write(tmp_path, chain, body=BODY):
    p = tmp_path / "d.acl"
    p.write_text(HEAD + chain + body)
    return str(p)


def test_the_papers_bench_resolves_with_datasheet_values(tmp_path):
    d = acl.load(_write(tmp_path, "use generator bench.afg2225\nuse amplifier bench.hva200\n"))
    assert (d.generator.max_voltage, d.generator.memory, d.generator.channels) == (10.0, 4096, 2)
    assert (d.amplifier.gain, d.amplifier.max_voltage, d.amplifier.bandwidth) == (20.0, 200.0, 1e6)
    assert "DATASHEET VALUES" in open(os.path.join(ROOT, "stdlib", "bench.acl")).read()


def test_a_drive_beyond_the_amplifier_is_a_located_error(tmp_path, capsys):
    chain = "use generator bench.afg2225\namplifier weak { gain = 2\n  max_voltage = 4 V }\n"
    path = _write(tmp_path, chain)
    assert main(["check", path]) == 1
    err = capsys.readouterr().err
    line = (HEAD + chain + BODY).splitlines().index("  drive 85 kHz @ 3 V + 125 kHz @ 2 V for 20 ms") + 1
    assert f"d.acl:{line}:3: error[E502]: 5 V exceeds the 4 V output of amplifier `weak`" in err


def test_a_drive_beyond_what_the_generator_can_feed_is_a_located_error(tmp_path, capsys):
    chain = "generator small { max_voltage = 0.2 V }\nuse amplifier bench.hva200\n"
    assert main(["check", _write(tmp_path, chain)]) == 1
    err = capsys.readouterr().err
    assert "error[E502]: 5 V needs 0.25 V from generator `small` through amplifier `bench.hva200` (gain 20)" in err


def test_a_tone_beyond_the_amplifier_bandwidth(tmp_path, capsys):
    chain = "amplifier slow { gain = 20\n  max_voltage = 200 V\n  bandwidth = 100 kHz }\n"
    assert main(["check", _write(tmp_path, chain)]) == 1
    assert "error[E501]: 125 kHz is beyond the 100 kHz bandwidth of amplifier `slow`" in capsys.readouterr().err


def test_bad_declarations(tmp_path, capsys):
    assert main(["check", _write(tmp_path, "amplifier a { gain = -3\n  max_voltage = 200 V }\n")]) == 1
    assert "E401" in capsys.readouterr().err
    assert main(["check", _write(tmp_path, "amplifier a { gain = 20 }\n")]) == 1
    assert "max_voltage" in capsys.readouterr().err
    assert main(["check", _write(tmp_path, "generator g { max_voltage = 3 kHz }\n")]) == 1
    assert "E301" in capsys.readouterr().err


EXAMPLES = sorted(f for f in os.listdir(os.path.join(ROOT, "examples")) if f.endswith(".acl"))


@pytest.mark.parametrize("example", EXAMPLES)
def test_every_example_accepts_the_papers_bench(example, tmp_path):
    """Issue 26: the paper's bench declaration (AFG-2225 -> HVA200: 200 V, 1 MHz, 10 V x 20) accepts
    every example's programs (acl check: each explicit drive, sweep and goal limit)."""
    import shutil

    shutil.copytree(os.path.join(ROOT, "examples"), tmp_path / "examples")   # some extend others
    src = open(os.path.join(ROOT, "examples", example)).read()
    p = tmp_path / "examples" / example
    p.write_text(src + "\nimport stdlib.bench\nuse generator bench.afg2225\nuse amplifier bench.hva200\n")
    d = acl.load(str(p))
    assert d.amplifier is not None and d.generator is not None


def test_compile_checks_the_generators_rate_and_memory(tmp_path, capsys):
    """A sample rate above the declared generator's is a located error (E-EMIT-RATE at --sample-rate);
    a waveform beyond its memory a warning pointing to acl play (W-EMIT-MEMORY)."""
    path = _write(tmp_path, "use generator bench.afg2225\nuse amplifier bench.hva200\n")
    assert main(["compile", path, "-o", str(tmp_path / "o1"), "--sample-rate", "200MHz"]) == 2
    err = capsys.readouterr().err
    assert "<--sample-rate>:1:1: error[E-EMIT-RATE]: sample rate 2e+08 S/s is above the 1.2e+08 S/s of generator " \
           "`bench.afg2225`" in err and not (tmp_path / "o1").exists()
    assert main(["compile", path, "-o", str(tmp_path / "o2"), "-q"]) == 0
    err = capsys.readouterr().err
    assert "warning[W-EMIT-MEMORY]: the waveform's 25,000 samples do not fit the 4,096 points of generator " \
           "`bench.afg2225`" in err
