"""Benchmark of `acl fmt`: time to format a generated design of N lines (default 1,000).

    python benchmarks/fmt.py [--lines 1000] [--runs 5]

Prints the median time of `acl.fmt.format_source` on a badly laid out design (every layout rule
at work, with the parse of the result and the syntax-tree comparison that guards the meaning) and
on the same design already formatted (the common case in CI and format-on-save: one parse and
the layout, no re-parse). The issue sets no target for the formatter; the language server's
format request goes through the same function.
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


def median_ms(f, runs: int) -> float:
    times = []
    for _ in range(runs):
        t = time.perf_counter()
        f()
        times.append(time.perf_counter() - t)
    return statistics.median(times) * 1e3


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--lines", type=int, default=1000)
    ap.add_argument("--runs", type=int, default=5)
    args = ap.parse_args()
    from acl.fmt import format_source

    messy = design(args.lines)
    tidy = format_source(messy)   # warm-up: grammar loaded
    assert format_source(tidy) == tidy
    n = messy.count("\n")
    ms_messy = median_ms(lambda: format_source(messy + " "), args.runs)
    ms_tidy = median_ms(lambda: format_source(tidy), args.runs)
    print(f"acl fmt, {n} lines: {ms_messy:.0f} ms to reformat ({n / ms_messy * 1e3:,.0f} lines/s), "
          f"{ms_tidy:.0f} ms when already formatted ({n / ms_tidy * 1e3:,.0f} lines/s); median of {args.runs}")


if __name__ == "__main__":
    main()
