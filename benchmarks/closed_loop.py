"""Closed loop over seeded truths (issue 9, done-when bullet 2): prints the figures docs/fit.md quotes.

    python benchmarks/closed_loop.py [--kind stroke|fig3|pair-hold] [--seeds 20] [--band-samples 20] [--json PATH]
                                     [--model eq3|coupled]

``--kind stroke`` (default): each seed draws a truth from examples/fig2_stroke.acl (a cantilever along
one axis; acl.fit.loop.seeded_truth: a per-tone gain tilt so the 110 and 140 kHz tones differ by up to
30 %, a level 0.85-1.15 and an undeclared drive saturation V_s 5-10 V).
``--kind fig3``: the Fig. 3 three-orifice module in the plane, program `rectangle` (x and y, three
tones the compiler picks, 72.5-178.5 kHz): the tilt makes the outer tones differ by up to 30 %, level
0.85-1.15, V_s 14-28 V; compiled with allow_nonlinear (the nominal plan touches eps/R = 0.257).
Then compile -> play (noise 0.05 um) -> fit (--free gamma) -> recompile -> play.
Reported per seed: tracking error before / after calibration / floor (compiled on the truth), the
calibrated compile's predicted error and 95 % band, and whether the band covers the re-simulated error.
``--kind pair-hold``: the Fig. 4 facing pair (a goal without a path): the truth's gain level 0.8-1.25
and V_s 5-12 V; the `ramp` program (1..6 V at 125 kHz; the steps past snap-in give no row) is played
as the calibration run (noise 0.2 um), `acl fit --free gamma,alpha`, then `keep_apart` (hold the gap
above 10 um, margin 1.2) is compiled on the nominal and on the calibrated design; reported: the
truth's snap-in margin under each drive (acl.schedule.gains.critical_scale) and whether the
calibrated compile's 5th percentile of the margin (details.band.margin_p05) lies below it (covers).
``--model coupled`` (pair-hold only) fits the pair with `acl fit --model coupled` (the analysis' own forces)
instead of paper Eq. (3); each row records the fit's CPU time.
``--json PATH`` writes the rows (docs/fit.md renders the studies from benchmarks/closed_loop_{stroke,fig3,pair_hold}.json;
tests/test_closed_loop.py repeats one of its seeds).
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import tempfile
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

import numpy as np  # noqa: E402

from acl.fit.loop import run_loop, seeded_truth  # noqa: E402

HERE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "examples")

# kind -> (files to copy, nominal design, program, seeded_truth keywords, run_loop keywords)
KINDS = {
    "stroke": (("fig2_vertical_cantilever.acl", "fig2_stroke.acl"), "fig2_stroke.acl", "stroke", {}, {}),
    "fig3": (("fig3_three_orifice.acl",), "fig3_three_orifice.acl", "rectangle",
             {"span_hz": (72.5e3, 178.5e3), "v_sat": (14.0, 28.0)}, {"allow_nonlinear": True}),
}


def run_seed(kind: str, seed: int, tmp: str, band_samples: int = 20):
    """One seeded truth of ``kind`` through the whole loop in ``tmp``: (LoopResult, truth text)."""
    files, nominal, program, truth_kw, loop_kw = KINDS[kind]
    for name in files:
        shutil.copy(os.path.join(HERE, name), tmp)
    rng = np.random.default_rng(1000 + seed)
    text = seeded_truth("", rng, nominal, **truth_kw)
    truth = os.path.join(tmp, f"truth{seed}.acl")
    with open(truth, "w") as fh:
        fh.write(text)
    work = os.path.join(tmp, f"w{seed}")
    os.makedirs(work, exist_ok=True)
    return run_loop(os.path.join(tmp, nominal), truth, program, work, seed=seed,
                    band_samples=band_samples, **loop_kw), text


def run_hold_seed(seed: int, tmp: str, band_samples: int = 20, model: str = "eq3") -> dict:
    """One seeded truth of the pair-hold study (above) in ``tmp``: a row."""
    import acl
    from acl.fit import run_fit
    from acl.fit.loop import _compile, _play
    from acl.fit.synth import write_csv
    from acl.schedule.compile import CompileOptions
    from acl.schedule.gains import critical_scale

    # the Fig. 4 pair before its stdlib calibration (the first-principles pair law this study was recorded with)
    shutil.copy(os.path.join(HERE, "first_principles", "fig4_facing_pair.acl"),
                os.path.join(tmp, "fig4_facing_pair.acl"))
    nominal = os.path.join(tmp, "fig4_facing_pair.acl")
    rng = np.random.default_rng(2000 + seed)
    text = (f'extends "fig4_facing_pair.acl"\n'
            f"effect transducer_gain {{ gain_slope = 0, f_ref = 125 kHz, gain = {rng.uniform(0.8, 1.25):.6g} }}\n"
            f"effect drive_saturation {{ v_sat = {rng.uniform(5.0, 12.0):.6g} V }}\n")
    truth_path = os.path.join(tmp, f"pair_truth{seed}.acl")
    with open(truth_path, "w") as fh:
        fh.write(text)
    truth = acl.load(truth_path)
    run = _play(truth, _compile(nominal, "ramp", CompileOptions()), noise=0.2e-6, seed=seed)
    data = os.path.join(tmp, f"pair_run{seed}.csv")
    write_csv(run.data, data)
    cal = os.path.join(tmp, f"pair{seed}.calibrated.acl")
    t0 = time.process_time()
    out = run_fit(nominal, [data], free=("gamma", "alpha"), seed=seed, calibrated_path=cal, model=model)
    fit_cpu = time.process_time() - t0
    with open(cal, "w", encoding="utf-8") as fh:
        fh.write(out.calibrated)
    paths = [tmp]
    opts = CompileOptions(band_samples=band_samples, band_seed=seed, allow_nonlinear=True,
                          reload=lambda ov: acl.load(cal, overrides=ov, search_paths=paths))
    s1 = _compile(cal, "keep_apart", opts, paths)
    s0 = _compile(nominal, "keep_apart", CompileOptions(allow_nonlinear=True))

    def margin(sched):
        seg = next(x for x in sched.segments if x.tones)
        tones = [(t.frequency_hz, t.amplitude_v) for t in seg.tones]
        return float(critical_scale(truth, "left.jet", "right.jet", tones, 3.0, 10e-6)), sum(a for _, a in tones)

    m0, v0 = margin(s0)
    m1, v1 = margin(s1)
    g = s1.goals[0]
    band = g.details.get("band", {})
    return {"seed": seed, "truth": text, "rows": int(run.data.n), "lost": int(run.lost),
            "effects": list(out.selection.selected), "before_margin": m0, "before_v": v0,
            "after_margin": m1, "after_v": v1, "promised": g.details.get("resimulated_margin"),
            "margin_p05": band.get("margin_p05"), "draws_below_1": band.get("draws_below_1"),
            "covered": band.get("margin_p05") is not None and m1 >= band["margin_p05"],
            "warned": any(n.startswith("warning:") and "snaps the pair in" in n for n in s1.notes),
            "model": model, "fit_cpu_s": fit_cpu}


def row(seed: int, r, text: str) -> dict:
    return {"seed": seed, "truth": text, "before_rms_m": r.before_rms_m, "before_max_m": r.before_max_m,
            "after_rms_m": r.after_rms_m, "after_max_m": r.after_max_m, "floor_rms_m": r.floor_rms_m,
            "floor_max_m": r.floor_max_m, "predicted_rms_m": r.predicted_rms_m,
            "band_rms_p95_m": r.band_rms_p95_m, "band_max_p95_m": r.band_max_p95_m, "covered": r.covered,
            "effects": r.effects, "warned": any(n.startswith("warning:") and "calibrat" in n for n in r.notes),
            "unmeasured_tone": any("did not measure the transducer gain" in n for n in r.notes)}


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--kind", choices=sorted(KINDS) + ["pair-hold"], default="stroke")
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--band-samples", type=int, default=20)
    ap.add_argument("--json", help="write the per-seed rows here")
    ap.add_argument("--model", choices=("eq3", "coupled"), default="eq3",
                    help="pair-hold: the fit's pair model (acl fit --model; default eq3)")
    args = ap.parse_args()
    rows, out = [], []
    if args.kind == "pair-hold":
        with tempfile.TemporaryDirectory() as tmp:
            for seed in range(args.seeds):
                t0 = time.perf_counter()
                r = run_hold_seed(seed, tmp, args.band_samples, args.model)
                out.append(r)
                print(f"seed {seed:2d}: {r['rows']} rows ({r['lost']} lost to snap-in), effects {r['effects']}; "
                      f"nominal drive {r['before_v']:.3g} V: truth margin {r['before_margin']:.3g}; calibrated drive "
                      f"{r['after_v']:.3g} V: truth margin {r['after_margin']:.3g} (promised {r['promised']:.3g}, "
                      f"p05 {r['margin_p05']:.3g}, {r['draws_below_1']}/{args.band_samples} draws below 1); "
                      f"covered {r['covered']}; fit {r['fit_cpu_s']:.1f} s CPU; {time.perf_counter() - t0:.0f} s",
                      flush=True)
        print(f"{len(out)} truths ({args.model}): nominal drive snaps the truth in {sum(r['before_margin'] < 1 for r in out)}; "
              f"calibrated drive snaps it in {sum(r['after_margin'] < 1 for r in out)}, warned in "
              f"{sum(r['warned'] for r in out)}; the margin band covers the truth's margin in "
              f"{sum(r['covered'] for r in out)} of {len(out)}")
        _write(args, out)
        return 0
    with tempfile.TemporaryDirectory() as tmp:
        for seed in range(args.seeds):
            t0 = time.perf_counter()
            r, text = run_seed(args.kind, seed, tmp, args.band_samples)
            rows.append(r)
            out.append(row(seed, r, text))
            print(f"seed {seed:2d}: before {r.before_rms_m * 1e6:.3f} um, after {r.after_rms_m * 1e6:.3f} um, "
                  f"floor {r.floor_rms_m * 1e6:.3f} um, after/floor {r.after_rms_m / r.floor_rms_m:.2f}; "
                  f"predicted {r.predicted_rms_m * 1e6:.3f}, band p95 {r.band_rms_p95_m * 1e6:.3f} / "
                  f"max {r.band_max_p95_m * 1e6:.3f} um (after max {r.after_max_m * 1e6:.3f}); "
                  f"covered {r.covered}; effects {r.effects}; {time.perf_counter() - t0:.0f} s", flush=True)
    ratio = np.array([r.after_rms_m / r.floor_rms_m for r in rows])
    cover = np.mean([r.covered for r in rows])
    print(f"{len(rows)} truths: before {np.median([r.before_rms_m for r in rows]) * 1e6:.3f} um RMS (median), "
          f"after {np.median([r.after_rms_m for r in rows]) * 1e6:.3f} um, floor "
          f"{np.median([r.floor_rms_m for r in rows]) * 1e6:.3f} um; after/floor max {ratio.max():.2f} "
          f"(<= 3 in {np.mean(ratio <= 3) * 100:.0f} %); band covers the re-simulated error in {cover * 100:.0f} % "
          f"({sum(r.covered for r in rows)} of {len(rows)}); band / error (RMS) median "
          f"{np.median([r.band_rms_p95_m / r.after_rms_m for r in rows]):.2f}, max "
          f"{np.max([r.band_rms_p95_m / r.after_rms_m for r in rows]):.2f}")
    _write(args, out)
    return 0


def code_version() -> str:
    """The commit the run's code is (read when the run starts: a commit made while it runs is not its code), with
    "+changes" when acl/ differs from it."""
    import subprocess

    here = os.path.dirname(os.path.abspath(__file__))
    try:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                                cwd=here).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--", "../acl"], capture_output=True, text=True,
                               cwd=here).stdout.strip()
    except OSError:
        return "unknown"
    return (commit or "unknown") + ("+changes" if dirty else "")


CODE = code_version()


def _write(args, out) -> None:
    if args.json:
        commit = CODE
        with open(args.json, "w") as fh:
            json.dump({"kind": args.kind, "band_samples": args.band_samples, "code": commit, "rows": out,
                       **({"model": args.model} if args.kind == "pair-hold" else {})}, fh, indent=1)


if __name__ == "__main__":
    sys.exit(main())
