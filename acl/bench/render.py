"""Synthetic microscope videos of a known trajectory (for the tracker's tests and benchmark).

A capsule-like disc (a bright interior with a dark rim, soft edge) on an unevenly lit background
(a tilted and curved illumination, a fixed speckle texture), with optical blur (the soft edge),
motion blur (each frame averages sub-frame positions), a slow drift and a flickering lamp, and
Gaussian noise at a given SNR: 20 log10(disc contrast / noise standard deviation) dB.
"""
from __future__ import annotations

import math

import numpy as np


def trajectory(n: int, fps: float, radius_px: float = 3.0, period_s: float = 1.0,
               drift_px_s: tuple[float, float] = (0.8, -0.5), center=(0.0, 0.0)):
    """(x, y) in px of a circle of ``radius_px`` per ``period_s`` plus a linear drift, at frame times."""
    t = np.arange(n) / fps
    x = center[0] + radius_px * (np.cos(2 * math.pi * t / period_s) - 1.0) + drift_px_s[0] * t
    y = center[1] + radius_px * np.sin(2 * math.pi * t / period_s) + drift_px_s[1] * t
    return x, y


def background(width: int, height: int, seed: int = 0) -> np.ndarray:
    """Unevenly lit background: a tilt, a curvature and a fixed speckle texture."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:height, 0:width].astype(np.float64)
    light = 90.0 + 40.0 * xx / width + 25.0 * ((yy - height / 2) / height) ** 2
    speckle = rng.normal(0, 1.0, (height, width))
    from scipy.ndimage import gaussian_filter

    return light + 4.0 * gaussian_filter(speckle, 2.0)


def disc(xx, yy, cx, cy, radius: float, contrast: float) -> np.ndarray:
    """The capsule: interior +contrast, a dark rim, a soft (blurred) edge."""
    d = np.hypot(xx - cx, yy - cy) - radius
    inside = 0.5 * (1.0 - np.tanh(d / 0.8))
    rim = np.exp(-0.5 * (d / 1.3) ** 2)
    return contrast * inside - 0.6 * contrast * rim


def render(x, y, width: int, height: int, origin=(0.0, 0.0), radius: float = 12.0, contrast: float = 60.0,
           snr_db: float = 30.0, motion_substeps: int = 5, seed: int = 1, flicker: float = 0.03,
           dtype=np.uint8):
    """Frames (n, height, width) of the disc at ``origin + (x[i], y[i])``, motion-blurred between
    consecutive positions; noise sigma = contrast / 10**(snr_db / 20)."""
    rng = np.random.default_rng(seed)
    bg = background(width, height, seed)
    sigma = contrast / 10 ** (snr_db / 20)
    n = len(x)
    out = np.empty((n, height, width), dtype=dtype)
    yy, xx = np.mgrid[0:height, 0:width].astype(np.float64)
    box = int(radius + 8)
    for i in range(n):
        frame = bg.copy()
        acc = np.zeros_like(frame)
        x0, y0 = (x[i - 1], y[i - 1]) if i else (x[i], y[i])
        cxm, cym = origin[0] + x[i], origin[1] + y[i]
        ys = slice(max(0, int(cym) - box - 4), min(height, int(cym) + box + 5))
        xs = slice(max(0, int(cxm) - box - 4), min(width, int(cxm) + box + 5))
        for k in range(motion_substeps):       # exposure: the second half of the motion since the last frame
            f = 0.5 + 0.5 * (k + 0.5) / motion_substeps if motion_substeps > 1 else 1.0    # 1: no motion blur
            cx = origin[0] + x0 + f * (x[i] - x0)
            cy = origin[1] + y0 + f * (y[i] - y0)
            acc[ys, xs] += disc(xx[ys, xs], yy[ys, xs], cx, cy, radius, contrast)
        frame += acc / motion_substeps
        frame *= 1.0 + flicker * math.sin(2 * math.pi * i / 37.0)
        frame += rng.normal(0, sigma, frame.shape)
        if np.issubdtype(dtype, np.integer):
            info = np.iinfo(dtype)
            frame = np.clip(np.rint(frame), info.min, info.max)
        out[i] = frame.astype(dtype)
    return out


def blur_centre(x, y, motion_substeps: int = 5):
    """Where the motion-blurred disc of frame i is centred: the mean of its sub-frame positions."""
    x = np.asarray(x, float)
    y = np.asarray(y, float)
    xp = np.concatenate([[x[0]], x[:-1]])
    yp = np.concatenate([[y[0]], y[:-1]])
    f = np.mean([0.5 + 0.5 * (k + 0.5) / motion_substeps for k in range(motion_substeps)]) if motion_substeps > 1 else 1.0
    return xp + f * (x - xp), yp + f * (y - yp)


def write_video(path: str, frames, fps: float) -> None:
    """Grey frames (N, H, W) as a lossless FFV1 AVI through imageio-ffmpeg (the synthetic videos of the tests,
    the bench loop and benchmarks/track.py)."""
    import imageio_ffmpeg

    h, w = frames[0].shape
    writer = imageio_ffmpeg.write_frames(path, (w, h), pix_fmt_in="gray", pix_fmt_out="gray", codec="ffv1",
                                         fps=fps, macro_block_size=1, quality=None)
    writer.send(None)
    for f in frames:
        writer.send(np.ascontiguousarray(f))
    writer.close()
