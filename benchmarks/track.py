"""Benchmark of `acl track`: frames per second on 512x512 frames, and the tracking error.

    python benchmarks/track.py [--frames 300] [--roi 48] [--snr 30]

Renders a synthetic microscope video (acl.bench.render: a capsule-like disc of radius 12 px on an
unevenly lit, textured background, motion blur, drift, lamp flicker, noise at --snr dB) of 512x512
frames, writes it as a lossless AVI (FFV1) and as a TIFF stack, and times `acl.bench.track.track_video`
on each (decoding included; rendering and writing not): wall time and process CPU time (on a
shared machine the wall time includes waiting for a core).  Prints the RMS error against the
known trajectory in pixels.  Target (issue 26): >= 100 frames/s; < 0.05 px RMS at 30 dB.
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=300)
    ap.add_argument("--roi", type=int, default=48, help="template side in px (centred on the capsule)")
    ap.add_argument("--snr", type=float, default=30.0)
    a = ap.parse_args()

    import tifffile

    from acl.bench.render import blur_centre, render, trajectory, write_video
    from acl.bench.track import track_video

    n, fps, size = a.frames, 100.0, 512
    origin = (250.4, 261.7)
    x, y = trajectory(n, fps, radius_px=4.0, period_s=1.0)
    frames = render(x, y, size, size, origin=origin, snr_db=a.snr)
    tx, ty = blur_centre(x, y)
    tx, ty = tx - tx[0], ty - ty[0]
    half = a.roi // 2
    roi = (int(origin[0]) - half, int(origin[1]) - half, a.roi, a.roi)
    with tempfile.TemporaryDirectory() as tmp:
        avi = os.path.join(tmp, "v.avi")
        write_video(avi, frames, fps)
        tif = os.path.join(tmp, "v.tif")
        tifffile.imwrite(tif, frames, imagej=True, metadata={"axes": "TYX", "finterval": 1 / fps})
        print(f"acl track: {n} frames of {size}x{size}, template {a.roi}x{a.roi} px, SNR {a.snr:g} dB")
        for name, path in (("AVI (FFV1)", avi), ("TIFF stack", tif)):
            w0, c0 = time.perf_counter(), time.process_time()
            tr = track_video(path, roi)
            wall, cpu = time.perf_counter() - w0, time.process_time() - c0
            ex, ey = tr.x - tx, tr.y - ty
            print(f"  {name:11s}: {n / wall:7.0f} frames/s wall, {n / cpu:7.0f} frames/s CPU; "
                  f"RMS error x {np.sqrt(np.mean(ex ** 2)):.4f} px, y {np.sqrt(np.mean(ey ** 2)):.4f} px; "
                  f"median sigma {np.median(tr.sigma_x):.4f} px")
    return 0


if __name__ == "__main__":
    sys.exit(main())
