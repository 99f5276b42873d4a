"""Two messages a new user hit on the shipped examples (newcomer review):

* `acl compile examples/fig2_vertical_cantilever.acl --program ramp` said step 6's forces carry a model-form
  uncertainty "of 0%" (a 0.16 % uncertainty rounded to nothing, printed beside a non-zero eps/R excess);
* `acl check examples/fig5a_gripper.acl` warned W402 on the paper's own Fig. 5b calibration
  (bjerknes_scale.factor 14.985 "outside its plausible range 0.1 .. 10"): a warning the paper's measurement
  contradicts.  The plausible top is now the 97.5 % quantile of the measured / first-principles pair ratios.
"""
from __future__ import annotations

import os
import re

from acl.cli import main
from acl.physics.constants import PAIR_SCALE_ROWS, pair_ratio_fit_quantile
from acl.physics.effect_table import EFFECT_TABLE

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
EX = os.path.join(ROOT, "examples")


def _factor_range():
    spec = EFFECT_TABLE["bjerknes_scale"]
    return next(c for c in spec.coefficients if c.name == "factor").range


def test_no_percentage_of_a_nonzero_uncertainty_prints_as_zero(tmp_path, capsys):
    main(["compile", os.path.join(EX, "fig2_vertical_cantilever.acl"), "--program", "ramp", "-o",
          str(tmp_path / "out")])
    err = capsys.readouterr().err
    shown = re.findall(r"(?:uncertainty of|other limits:) ([0-9.eE+-]+) ?%", err)
    assert shown, err[-2000:]
    assert all(float(v) > 0 for v in shown), shown


def test_every_measured_pair_ratio_is_plausible(tmp_path, capsys):
    rng = _factor_range()
    assert all(rng.plausible_lo <= r <= rng.plausible_hi for _, r in PAIR_SCALE_ROWS)
    assert rng.plausible_hi >= pair_ratio_fit_quantile(0.975)
    assert main(["check", os.path.join(EX, "fig5a_gripper.acl")]) == 0
    assert "W402" not in capsys.readouterr().err


def test_a_factor_beyond_the_evidence_still_warns(tmp_path, capsys):
    rng = _factor_range()
    src = open(os.path.join(EX, "fig5a_gripper.acl")).read()
    assert "factor = calibrations.gripper_pair_factor" in src
    design = tmp_path / "d.acl"
    design.write_text(src.replace("factor = calibrations.gripper_pair_factor", f"factor = {2 * rng.plausible_hi:g}"))
    main(["check", str(design)])
    assert "W402" in capsys.readouterr().err
