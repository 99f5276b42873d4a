"""A synthetic bench run: the video a microscope would record while a schedule plays on a design.

Used by the tests and docs/bench.md to close the loop compile -> play -> track -> fit without a
bench: ``acl synth TRUTH --schedule`` gives the capsule's displacement at every waypoint, and
:func:`video_of_waypoints` renders the frames (acl.bench.render) with the capsule where the
waypoint in force at each frame puts it.
"""
from __future__ import annotations

import numpy as np


def read_waypoints(path: str, name: str):
    """(times, x, y) of NAME_x and NAME_y rows of an `acl synth --schedule` CSV (um)."""
    rows = [line.split(",") for line in open(path, encoding="utf-8").read().splitlines()[1:] if line]
    t = np.array([float(r[4]) for r in rows if r[0] == f"{name}_x"])
    x = np.array([float(r[1]) for r in rows if r[0] == f"{name}_x"])
    y = np.array([float(r[1]) for r in rows if r[0] == f"{name}_y"])
    return t, x, y


def video_of_waypoints(csv_path: str, name: str, out_path: str, fps: float, frames: int, scale_um: float,
                       size: int = 128, origin=(70.3, 62.6), snr_db: float = 30.0, seed: int = 1):
    """Write a lossless AVI (FFV1) of the capsule at the waypoints' displacements (image axes: x right,
    y down; ``scale_um`` um per pixel); returns the true displacements (px) of each frame."""
    from acl.bench.render import render, write_video

    wt, wx, wy = read_waypoints(csv_path, name)
    t = np.arange(frames) / fps
    k = np.clip(np.searchsorted(wt, t + 1e-9, side="right") - 1, 0, len(wt) - 1)
    x, y = wx[k] / scale_um, wy[k] / scale_um
    video = render(x, y, size, size, origin=origin, snr_db=snr_db, motion_substeps=1, seed=seed)
    write_video(out_path, video, fps)
    return x - x[0], y - y[0]
