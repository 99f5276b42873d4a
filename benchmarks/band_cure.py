"""The band's cure through the lab's commands over many truths (issue 28): prints the figures tests/test_band_cure_cli.py
quotes for 20 truths.

    python benchmarks/band_cure.py [--truths 20] [--json PATH]

Each truth is drawn from the declared prior of examples/fig3_three_orifice.acl (rng seed 28, as the test): `acl
compile` proposes readings, `acl synth` makes them on the truth, `acl fit --free gain` calibrates, `acl compile`
recompiles and `acl synth --schedule` plays the program on the truth (tests/test_band_cure_cli.py's loop; about a
minute per truth on a loaded 2-core machine).  The loop takes the first goal's proposed readings, so each goal is held
to the band compile promises on those (the first goal's own promise; a later goal's `with_readings_of`).  Reported
per goal: the promised band, the achieved error (median, 90th percentile, maximum, how many truths within the promise
and 1.5x it, the promise over the median achieved error), how many recompiled bands cover it.  ``--json`` keeps
every truth's draw, the promise and the achieved errors.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "tests"))


class _Tmp:
    def __init__(self, root):
        self.root = Path(root)

    def mktemp(self, name):
        p = self.root / name
        p.mkdir(parents=True)
        return p


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--truths", type=int, default=20)
    ap.add_argument("--json", default=None)
    args = ap.parse_args(argv)
    import test_band_cure_cli as study

    study.TRUTHS = args.truths
    with tempfile.TemporaryDirectory() as tmp:
        expected, rows, tones = study.loop.__wrapped__(_Tmp(tmp))
    achieved = np.array([r[1] for r in rows])
    band = np.array([r[2] for r in rows])
    print(f"read tones: {', '.join(f'{f / 1e3:g}' for f in tones)} kHz; truths: {len(rows)}")
    for g, e in enumerate(expected):
        a, b = achieved[:, g], band[:, g]
        print(f"goal {g + 1}: promised {e:.3g} um; achieved median {np.median(a):.3g}, p90 {np.quantile(a, 0.9):.3g}, "
              f"max {a.max():.3g} um; within the promise {int((a <= e).sum())} of {a.size}, within 1.5x "
              f"{int((a <= 1.5 * e).sum())}; promise / median achieved {e / np.median(a):.3g}; "
              f"covered by the recompiled band {int((a <= b).sum())} (median band {np.median(b):.3g} um)")
    played = sum(all(sorted(f) == sorted(tones) and not u for f, u in r[4]) for r in rows)
    print(f"recompiles that played the read tones at every goal: {played} of {len(rows)}")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump({"expected_um": expected, "tones_hz": tones,
                       "rows": [{"before_um": r[0], "achieved_um": r[1], "band_um": r[2], "truth_z": r[5]}
                                for r in rows]}, fh, indent=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
