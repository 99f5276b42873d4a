"""Help that fits the case (issue 28, "Output that explains itself"): each message below said something that
did not apply, or left out what the user needed."""
from __future__ import annotations

import os
from types import SimpleNamespace

from acl.cli import main

DATA = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "samples")

TRUSSED = """import stdlib.beams
import stdlib.capsules
import stdlib.media
import stdlib.transducers
use medium media.pbs
use transducer transducers.contact_piezo
beam arm like beams.cantilever50 { clamp = (0, 0, 0) }
capsule a like capsules.design1 { }
capsule b like capsules.design1 { center = (0, 60 um, 68.6 um) }
mount a on arm.tip
truss tie { }
link b to a with tie
program p {
  follow b along polyline([(0, 0), (-2 um, 0)]) in 1 s, using [110 kHz, 125 kHz]
}
"""


def test_e509_on_a_trussed_capsule_says_to_follow_its_carrier(tmp_path, capsys):
    (tmp_path / "t.acl").write_text(TRUSSED)
    assert main(["check", str(tmp_path / "t.acl")]) == 1
    err = capsys.readouterr().err
    assert "error[E509]" in err and "follow `a` instead" in err, err
    assert "mount it" not in err


def test_e509_on_a_loose_capsule_still_says_mount_it(tmp_path, capsys):
    (tmp_path / "t.acl").write_text(TRUSSED.replace("link b to a with tie\n", "fix b\n"))
    assert main(["check", str(tmp_path / "t.acl")]) == 1
    err = capsys.readouterr().err
    assert "error[E509]" in err and "mount b on BEAM.tip" in err, err


def test_w401_and_e405_hints_name_the_link(tmp_path, capsys):
    src = TRUSSED.replace("link b to a with tie\n", "").replace("program p {\n  follow b along polyline([(0, 0), (-2 um, 0)]) in 1 s, using [110 kHz, 125 kHz]\n}\n", "")
    (tmp_path / "w.acl").write_text(src)
    main(["check", str(tmp_path / "w.acl")])
    err = capsys.readouterr().err
    assert "warning[W401]" in err and "link b to OTHER with TRUSS" in err, err
    (tmp_path / "e.acl").write_text(src + "mount b on arm.tip\n")
    assert main(["check", str(tmp_path / "e.acl")]) == 1
    err = capsys.readouterr().err
    assert "error[E405]" in err and "link SECOND to FIRST with TRUSS" in err, err


def test_synth_prints_planted_values_with_their_units(tmp_path, capsys):
    assert main(["synth", os.path.join(DATA, "fit_cantilever.acl"), "-o", str(tmp_path / "d.csv"),
                 "--voltages", "0V..2V:5", "--effect", "drive_saturation=v_sat:8V"]) == 0
    out = capsys.readouterr()
    text = out.out + out.err
    assert "planted drive_saturation: v_sat = 8 V" in text and "SI units" not in text, text


def test_a_rejected_candidate_that_passed_its_tests_says_why_it_was_not_kept():
    from acl.fit.select import _explain_rejections

    lone = SimpleNamespace(status="rejected", reason="passes F-test and BIC")
    beaten = SimpleNamespace(status="rejected", reason="passes F-test and BIC; drift explains more (lower BIC)")
    kept = SimpleNamespace(status="selected", reason="passes F-test, BIC and cross-validation")
    _explain_rejections([lone, beaten, kept])
    assert lone.reason.startswith("passed F-test and BIC, but was not kept")
    assert beaten.reason == "passed F-test and BIC, but drift explains more (lower BIC)"
    assert kept.reason == "passes F-test, BIC and cross-validation"


def test_an_80_column_terminal_sees_every_number(tmp_path):
    """The analyze pair table was cut to `lef…`, `125…`, `att…` at 80 columns; now too wide a table is stacked."""
    import subprocess
    import sys

    root = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
    env = dict(os.environ, COLUMNS="80", PYTHONPATH=root)
    r = subprocess.run([sys.executable, "-m", "acl", "analyze", os.path.join(root, "examples", "fig4_facing_pair.acl")],
                       env=env, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert "…" not in r.stdout
    block = r.stdout[r.stdout.index("Bubble pairs"):]
    assert "left-right" in block and "125.0" in block and "1.89" in block and "attract" in block   # snap-in V
    assert max(len(line) for line in r.stdout.splitlines()) <= 80


def test_acl_rule_examples_can_be_pasted_as_they_stand(tmp_path, capsys):
    """`acl rule ACL201` printed examples without their imports: pasted into a file they were E201."""
    import re

    assert main(["rule", "ACL201"]) == 0
    page = capsys.readouterr().out
    blocks = dict(re.findall(r"```acl (fails|passes)\n(.*?)```", page, re.S))
    for kind, body in blocks.items():
        f = tmp_path / f"{kind}.acl"
        f.write_text(body)
        code = main(["lint", str(f), "--output-format", "json"])
        out = capsys.readouterr().out
        assert '"E201"' not in out and "E2" not in out.split('"code"')[0], out[:300]
        assert ('"ACL201"' in out) == (kind == "fails"), (kind, code, out[:500])
