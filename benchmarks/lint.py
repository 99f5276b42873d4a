"""Benchmark `acl lint`: lint N generated designs in one process and print the time per design;
then one large design (the generator of benchmarks/check.py) of each size, each in its own process.

    python benchmarks/lint.py [N] [--large=1000,2500,5000]     (default 200 small designs)

Each large design's CPU time is also given as a ratio to a fresh `python -c "import cvxpy"` run next to it.

Designs are variations (seeded) of four shapes: one cantilever, a facing pair, a frequency-
selective pair and a latch, each with programs, so that every rule family runs.  The first design
pays the start-up (imports, grammar, stdlib); the figure that matters is the time per design after
it (target < 50 ms).  The large designs show how lint scales with the size of one design (issue 23:
5,000 lines in at most 5 s and 300 MB peak; it took 57 s and 1 GB).  Wall time depends on the machine's
load (printed); CPU time is what the lint costs.

Issue 23, branch engine4 (one interleaved run, two rounds, load average 8-10 on 2 cores; `python -c "import cvxpy"`
0.79 / 0.74 s CPU): 5,000 lines on abf535b 9.33 / 9.42 s CPU = 11.8x / 12.7x cvxpy's import, 200 MB peak; on
engine4 6.00 / 6.43 s CPU = 7.6x / 8.7x, 188 MB (0.64x / 0.68x of abf535b).  Still above the 5 s target: the
coupled response at rest (363 frequencies x 393 interfaces, one dense complex solve each) is about 2.8 s of it.

Issue 23, branch lint6 (one interleaved run, two rounds, load average 12 on 2 cores; `python -c "import cvxpy"`
0.95-1.01 s CPU): 5,000 lines on ab4c61b 7.01 / 6.95 s CPU (7.4x / 7.0x cvxpy's import), 188 MB peak; on lint6
4.79 / 4.87 s CPU (5.0x / 4.9x), 187-190 MB (0.68x / 0.70x of ab4c61b; the parse + resolve stage, 1.4-1.8 s of it, is
unchanged).  How: the Green matrix from the distinct pair geometries of the array (5,647 of 77,421; the coupled solve
2.95 -> 1.85 s, the LU solves themselves, 1.35 s, are what is left of it), the pair table's interface-pair geometry
kept per design, alike capsules' modes and the engine's drive-independent factors computed once.  The findings are
identical (benchmarks/lint_compare.py: 0 differences over 50 files and 26,159 findings).
"""
from __future__ import annotations

import random
import statistics
import sys
import tempfile
import time
from pathlib import Path

HEAD = """\
import stdlib.media
import stdlib.materials
import stdlib.capsules
import stdlib.beams
import stdlib.transducers
use medium media.pbs
use transducer transducers.contact_piezo
"""


def cantilever(rng: random.Random) -> str:
    r = rng.choice([8, 9, 10, 11, 12, 13])
    v = rng.uniform(1, 8)
    return HEAD + f"""\
param volts = {v:.2f} V
beam arm like beams.cantilever50 {{ clamp = (0, 0, 0) }}
capsule a like capsules.design1 {{ orifice jet {{ radius = {r} um, normal = +x }} }}
mount a on arm.tip
require resonance(a) in 60 kHz .. 180 kHz
program ramp {{
  drive 125 kHz @ volts for 1 s
  sweep 80 kHz to 160 kHz @ 2 V in 1 s
}}
"""


def pair(rng: random.Random) -> str:
    gap = rng.uniform(20, 90)
    return HEAD + f"""\
param gap = {gap:.1f} um
beam left_arm like beams.cantilever50 {{ clamp = (0, 0, 0) }}
beam right_arm like beams.cantilever50 {{ clamp = (54 um + gap, 0, 0) }}
capsule left like capsules.design1 {{ thrust = 0.027 nN/V^2 }}
capsule right like capsules.design1 {{ thrust = 0.027 nN/V^2, orifice jet {{ radius = 10 um, normal = -x }} }}
mount left on left_arm.tip
mount right on right_arm.tip
program ramp {{
  drive 125 kHz @ 2 V for 1 s
  drive 125 kHz @ 4 V for 1 s
}}
"""


def selective(rng: random.Random) -> str:
    spacing = rng.uniform(80, 200)
    return HEAD + f"""\
beam arm_low like beams.cantilever50 {{ clamp = (0, 0, 0) }}
beam arm_high like beams.cantilever50 {{ clamp = ({spacing:.1f} um, 0, 0) }}
capsule low like capsules.design2 {{ }}
capsule high like capsules.design3 {{ }}
mount low on arm_low.tip
mount high on arm_high.tip
require separation(low, high) >= 50 kHz
program sequential {{
  drive 85 kHz @ 3 V for 1 s
  drive 170 kHz @ 3 V for 1 s
}}
"""


def latch(rng: random.Random) -> str:
    angle = rng.choice([30, 45, 60])
    return HEAD + f"""\
latch l {{
  angle = {angle} deg
  length = 50 um
  width = {rng.choice([0.5, 0.8, 1.0])} um
  thickness = 1.7 um
  material = materials.tpeta
  at = (0, 0, 60 um)
  axis = +x
}}
capsule c like capsules.design1 {{ thrust = 0.027 nN/V^2, orifice jet {{ radius = 10 um, normal = -x }} }}
mount c on l.shuttle
program flip {{
  drive 100 kHz @ 5 V for 1 s
  switch l to b, margin 1.2, using [125 kHz], limit 20 V
}}
"""


SHAPES = (cantilever, pair, selective, latch)


def main(n: int = 200) -> None:
    t_import = time.perf_counter()
    from acl.lint import LintConfig, lint_file

    t_import = time.perf_counter() - t_import
    rng = random.Random(5)
    with tempfile.TemporaryDirectory() as tmp:
        paths = []
        for i in range(n):
            p = Path(tmp) / f"design_{i:03d}.acl"
            p.write_text(SHAPES[i % len(SHAPES)](rng))
            paths.append(str(p))
        cfg = LintConfig()
        times, cpus, checks, findings = [], [], [], 0
        for p in paths:
            t, c = time.perf_counter(), time.process_time()
            report = lint_file(p, cfg)
            times.append(time.perf_counter() - t)
            cpus.append(time.process_time() - c)
            checks.append(report.check_seconds)
            findings += len(report.findings)
            if not report.resolved:
                raise SystemExit(f"generated design does not resolve: {p}: {report.findings[0].message}")
    first, rest = times[0], times[1:]
    print(f"acl lint benchmark: {n} designs, {findings} findings")
    print(f"  import acl.lint:           {t_import * 1e3:8.1f} ms")
    print(f"  first design (start-up):   {first * 1e3:8.1f} ms")
    print(f"  per design after start-up: mean {statistics.mean(rest) * 1e3:.1f} ms, "
          f"median {statistics.median(rest) * 1e3:.1f} ms, max {max(rest) * 1e3:.1f} ms")
    print(f"    in CPU time:             mean {statistics.mean(cpus[1:]) * 1e3:.1f} ms, "
          f"median {statistics.median(cpus[1:]) * 1e3:.1f} ms (load average {__import__('os').getloadavg()[0]:.1f})")
    rules = [t - c for t, c in zip(rest, checks[1:])]
    print(f"    of which check stage:    mean {statistics.mean(checks[1:]) * 1e3:.1f} ms (parse + resolve + checks)")
    print(f"    of which lint rules:     mean {statistics.mean(rules) * 1e3:.1f} ms, max {max(rules) * 1e3:.1f} ms")
    print(f"  total:                     {sum(times):8.2f} s")
    import sys as _sys

    heavy = sorted(m for m in _sys.modules if m.split(".")[0] in ("cvxpy", "matplotlib"))
    print(f"  heavy modules imported:    {', '.join(heavy) or 'none'}")


def large(sizes: list[int]) -> None:
    """Lint one generated design (benchmarks/check.py's generator) of each of ``sizes`` lines, each in a fresh
    process: wall and CPU time of `lint_file` and the process's peak memory (targets, issue 23: 5,000 lines
    in at most 5 s and 300 MB)."""
    import os
    import subprocess

    import resource

    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep)}

    def import_cvxpy() -> float:
        """CPU seconds of a fresh `python -c "import cvxpy"` (the reference the issue's ratios use)."""
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        subprocess.run([sys.executable, "-c", "import cvxpy"], env=env, check=True)
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        return after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime

    for n in sizes:
        ref = import_cvxpy()          # interleaved with each lint, so that the ratio shares the load
        r = subprocess.run([sys.executable, __file__, f"--one={n}"], capture_output=True, text=True, env=env, check=False)
        if r.returncode != 0:
            raise SystemExit(f"large design of {n} lines failed:\n{r.stderr}")
        ref = min(ref, import_cvxpy())
        line = r.stdout.rstrip()
        cpu = float(line.split(" s CPU")[0].rsplit(" ", 1)[-1])
        print(f"{line}\n    = {cpu / ref:.2f}x `python -c \"import cvxpy\"` ({ref:.2f} s CPU, the lesser of two runs around it)")


def one(lines: int) -> None:
    """The child of :func:`large`: generate, lint once, print one line."""
    import importlib.util
    import os
    import resource

    from acl.lint import LintConfig, lint_file

    spec = importlib.util.spec_from_file_location("acl_benchmark_check", ROOT / "benchmarks" / "check.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    with tempfile.TemporaryDirectory() as tmp:
        p = Path(tmp) / f"large_{lines}.acl"
        text = mod.generate(lines)
        p.write_text(text)
        before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
        t, c = time.perf_counter(), time.process_time()
        report = lint_file(str(p), LintConfig())
        wall, cpu = time.perf_counter() - t, time.process_time() - c
        peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024      # kB on Linux
    print(f"  one design of {text.count(chr(10)):,} lines ({text.count('capsule ')} capsules): {wall:.2f} s wall, "
          f"{cpu:.2f} s CPU (check stage {report.check_seconds:.2f} s), peak memory {peak:.0f} MB "
          f"({before:.0f} MB before linting), {len(report.findings)} findings (load average {os.getloadavg()[0]:.1f})")


ROOT = Path(__file__).resolve().parents[1]

if __name__ == "__main__":
    single = next((int(a.split("=", 1)[1]) for a in sys.argv[1:] if a.startswith("--one=")), None)
    if single is not None:
        one(single)
        raise SystemExit(0)
    args = [a for a in sys.argv[1:] if not a.startswith("--large")]
    spec = next((a.split("=", 1)[1] for a in sys.argv[1:] if a.startswith("--large=")), "1000,2500,5000")
    main(int(args[0]) if args else 200)
    large([int(x) for x in spec.split(",") if x])
