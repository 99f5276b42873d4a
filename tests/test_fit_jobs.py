"""`acl fit --jobs N`: candidate effects of a round fitted on N forked worker processes give the same result as one
process, bit for bit (acl.fit.select._each), including a round that starts over when a candidate's solution turns
out to be a better fit of the current model (that path: benchmarks/fit.py case 3, which runs both and compares); bad
values of --jobs are usage errors."""
from __future__ import annotations

import os

import numpy as np
import pytest

from acl.fit.synth import Experiment, generate, write_csv

DATA = os.path.join(os.path.dirname(__file__), "..", "samples")
PAIR_CAL = os.path.join(DATA, "fit_pair_cal.acl")
FREQS = (105e3, 115e3, 125e3, 135e3, 145e3)

pytestmark = pytest.mark.skipif(not hasattr(os, "fork"), reason="worker processes are forked (POSIX only)")


def _pair_cal(tmp_path):
    gaps = {"gap": ["40 um", "55 um", "70 um"]}
    ex = [Experiment(frequencies=FREQS, voltages=tuple(np.linspace(0, 4, 7)), sets=gaps, observables=("distance",),
                     label="pair", interval=0.5),
          Experiment(frequencies=FREQS, voltages=tuple(np.linspace(0, 11, 12)), observables=("cal",),
                     label="calibration", interval=0.5)]
    # the reduced Eq. (3) pair model: the property (workers = one process, bit for bit) does not depend on the pair
    # model, and the default (coupled) model's search costs over 20x the CPU, too slow for the default set
    data, _ = generate(PAIR_CAL, ex, {"neighbour_drag": {"plateau": 8e-6}}, noise=0.2e-6, seed=7,
                       coeffs={"alpha": 1.745e-19}, model="eq3")
    path = str(tmp_path / "d.csv")
    write_csv(data, path)
    return path


def test_two_workers_give_the_same_search_as_one_process(tmp_path):
    from acl.fit.problem import load_problem
    from acl.fit.select import select_effects

    path = _pair_cal(tmp_path)
    runs = []
    for jobs in (1, 2):
        said = []
        sel = select_effects(load_problem(PAIR_CAL, [path], free=["gamma", "alpha"], model="eq3"), seed=7, jobs=jobs,
                             progress=said.append)
        runs.append((sel, said))
    (one, said1), (two, said2) = runs
    assert said1 == said2
    assert one.selected == two.selected == ["neighbour_drag"]
    assert [(t.effect, t.round, t.status, t.reason) for t in one.trials] == \
        [(t.effect, t.round, t.status, t.reason) for t in two.trials]
    for a, b in ((one.base, two.base), (one.final, two.final)):
        assert a.chi2 == b.chi2
        assert np.array_equal(a.values, b.values) and np.array_equal(a.prediction, b.prediction)
        assert np.array_equal(a.stderr, b.stderr, equal_nan=True)
    assert [(a["effects"], a["delta_chi2"]) for a in one.ambiguous] == \
        [(a["effects"], a["delta_chi2"]) for a in two.ambiguous]


def test_each_yields_in_order_and_stops_early():
    from acl.fit.select import _each

    assert list(_each(lambda x: x * x, range(7), jobs=3)) == [x * x for x in range(7)]
    gen = _each(lambda x: os.getpid(), range(4), jobs=2)
    pids = [next(gen), next(gen)]
    gen.close()                       # a round that starts over: the rest is cancelled, nothing hangs
    assert os.getpid() not in pids    # fitted in the workers


@pytest.mark.parametrize("value, why", [("0", "at least one process"), ("-2", "at least one process"),
                                        ("two", "not a number of processes")])
def test_bad_jobs_is_a_usage_error(tmp_path, capsys, value, why):
    from acl.cli import main

    csv = tmp_path / "d.csv"
    csv.write_text("observable,voltage,frequency,value\n")
    with pytest.raises(SystemExit) as stop:
        main(["fit", os.path.join(DATA, "fit_cantilever.acl"), str(csv), "--jobs", value])
    code = stop.value.code
    err = capsys.readouterr().err
    assert code == 2 and "<--jobs>:1:1: error[E-USAGE]" in err and why in err and "Traceback" not in err
