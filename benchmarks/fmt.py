"""Benchmark of `acl fmt`: time to format a generated design of N lines (default 10,000).

    python benchmarks/fmt.py [--lines 10000] [--runs 3]

Prints the median time of `acl.fmt.format_source` on a badly laid out design (every layout rule
at work, with the parse of the result and the syntax-tree comparison that guards the meaning) and
on the same design already formatted (the common case in CI and format-on-save: one parse and
the layout, no re-parse), the diff `acl fmt --check` prints, and `acl check`'s front end
(`acl.loads`: parse + resolve + checks) on the same formatted text for comparison. Each as wall
time and as process CPU time (on a shared machine the wall time includes waiting for a core).
Linearity: the same figures at half the size. Target (issue 11, item 3): about the lines/s of
`acl check` (~10,000 lines/s on a quiet machine); before the fix, 10,001 lines took 12-15 s.
"""
from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

HEADER = "import stdlib.transducers\nimport stdlib.media\nimport stdlib.capsules\nuse medium media.pbs\n"
BLOCK = """param gap{i}=40um # gap {i}
param reach{i} = 27 um      # reach
capsule c{i} like capsules.design1{{
    center=(2*reach{i}+gap{i},{i}*100 um,30um)
      orifice jet {{radius=10um,normal=-x}}
}}
program p{i} {{
      drive 125kHz@2V+85 kHz@ 1 V for 200ms,limit 5V
}}
"""


def design(lines: int) -> str:
    per = BLOCK.count("\n")
    return HEADER + "".join(BLOCK.format(i=i) for i in range(max(1, lines // per)))


def median_ms(f, runs: int) -> tuple[float, float]:
    """(wall ms, CPU ms), medians of ``runs`` calls."""
    wall, cpu = [], []
    for _ in range(runs):
        t, c = time.perf_counter(), time.process_time()
        f()
        wall.append(time.perf_counter() - t)
        cpu.append(time.process_time() - c)
    return statistics.median(wall) * 1e3, statistics.median(cpu) * 1e3


def figures(lines: int, runs: int) -> None:
    import os

    import acl
    from acl.fmt import format_source
    from acl.fmt.diff import unified_diff

    messy = design(lines)
    tidy = format_source(messy)
    assert format_source(tidy) == tidy
    n = messy.count("\n")
    a, b = messy.splitlines(keepends=True), tidy.splitlines(keepends=True)
    k = iter(range(10**9))
    rows = [
        ("reformat", median_ms(lambda: format_source(messy + " " * next(k)), runs)),
        ("already formatted", median_ms(lambda: format_source(tidy), runs)),
        ("--check diff", median_ms(lambda: sum(1 for _ in unified_diff(a, b, "x", "y")), runs)),
        ("acl check front end", median_ms(lambda: acl.loads(tidy + "#" * next(k) + "\n", "bench.acl"), runs)),
    ]
    print(f"{n:,} lines (median of {runs}; load average {os.getloadavg()[0]:.1f}):")
    for name, (wall, cpu) in rows:
        print(f"  {name:<20} {wall:8.0f} ms wall ({n / wall * 1e3:9,.0f} lines/s)  {cpu:8.0f} ms CPU "
              f"({n / cpu * 1e3:9,.0f} lines/s)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--lines", type=int, default=10_000)
    ap.add_argument("--runs", type=int, default=3)
    args = ap.parse_args()
    from acl.fmt import format_source

    format_source(design(100))   # warm-up: grammar loaded
    for lines in (args.lines // 2, args.lines):
        figures(lines, args.runs)


if __name__ == "__main__":
    main()
