"""Benchmark of `acl export`: time to export the largest example (target: under 2 s, issue 25).

    python benchmarks/export.py [--runs 5] [--design examples/figS6_flextensional.acl]

The largest example is the one with the most triangles in its print file (every example is built to
find it).  Prints the median over runs, as wall and process CPU time, of each stage of an export
without the interpreter's start: building the solids (manifold3d), encoding the STL and the 3MF,
reading the STL back and measuring it against the design (acl.export.measure), and their total;
and the whole command (`python -m acl export ... -q`) once, start-up included.
"""
from __future__ import annotations

import argparse
import io
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def _largest():
    from acl.design.resolve import load_design
    from acl.export.solid import build

    sizes = {}
    for ex in sorted((ROOT / "examples").glob("*.acl")):
        b = build(load_design(str(ex)))
        sizes[ex] = sum(p.solid.num_tri() for p in b.parts)
    best = max(sizes, key=sizes.get)
    return best, sizes[best]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--design", default=None)
    args = ap.parse_args()
    import trimesh

    from acl.design.resolve import load_design
    from acl.export import files
    from acl.export.measure import check
    from acl.export.solid import build

    if args.design:
        path, tris = Path(args.design), None
    else:
        path, tris = _largest()
    design = load_design(str(path))
    stages = {"build": [], "encode stl+3mf": [], "read back + measure": [], "total": []}
    cpu_total = []
    for _ in range(args.runs):
        t0, c0 = time.perf_counter(), time.process_time()
        b = build(design)
        t1 = time.perf_counter()
        meshes = files.meshes(b.parts)
        names = [p.name for p in b.parts]
        stl = files.encode(meshes, names, "stl")
        files.encode(meshes, names, "3mf")
        t2 = time.perf_counter()
        back = trimesh.load(io.BytesIO(stl), file_type="stl")
        _, diags = check(design, back)
        t3 = time.perf_counter()
        assert not [d for d in diags if d.is_error], diags
        stages["build"].append(t1 - t0)
        stages["encode stl+3mf"].append(t2 - t1)
        stages["read back + measure"].append(t3 - t2)
        stages["total"].append(t3 - t0)
        cpu_total.append(time.process_time() - c0)
    print(f"design: {path.relative_to(ROOT) if path.is_absolute() else path}"
          + (f" (largest example: {tris:,} triangles)" if tris else ""))
    for k, v in stages.items():
        print(f"  {k:<22} {statistics.median(v) * 1e3:8.1f} ms (median of {args.runs})")
    print(f"  {'total CPU':<22} {statistics.median(cpu_total) * 1e3:8.1f} ms")
    with tempfile.TemporaryDirectory() as tmp:
        t = time.perf_counter()
        r = subprocess.run([sys.executable, "-m", "acl", "export", str(path), "-o", f"{tmp}/x.stl", "-q"],
                           cwd=ROOT, capture_output=True, text=True)
        whole = time.perf_counter() - t
    print(f"  whole command (start-up included): {whole:.2f} s, exit {r.returncode}")
    total = statistics.median(stages["total"])
    print(f"export of the largest example: {total:.3f} s ({'under' if total < 2 else 'OVER'} the 2 s target, "
          f"{2 / total:.1f}x margin)")
    return 0 if total < 2 else 1


if __name__ == "__main__":
    sys.exit(main())
