"""Drive pressure: transducer gain (Pa per V) vs frequency, linear in voltage (paper Fig. 2e, Fig. S1).

The gain table is the measured transfer function of transducer + slide + electronics (paper
Fig. S1).  Between table points the gain is interpolated linearly; outside the table it is held at
the end value and flagged, so that the analysis or lint can decide how serious that is.
"""
from __future__ import annotations

import numpy as np


def pressure_per_volt(frequency, table_frequency, table_gain):
    """Gain (Pa/V) at ``frequency`` by linear interpolation of the table (paper Fig. S1); returns (gain, outside_mask).

    ``outside_mask`` is True where the frequency lies outside [table_frequency[0],
    table_frequency[-1]] (flat extrapolation used there).
    """
    f = np.asarray(frequency, float)
    tf = np.asarray(table_frequency, float)
    tg = np.asarray(table_gain, float)
    if tf.ndim != 1 or tf.size != tg.size or tf.size == 0:
        raise ValueError("gain table needs matching, non-empty 1-D frequency and gain arrays")
    if tf.size > 1 and np.any(np.diff(tf) <= 0):
        raise ValueError("gain table frequencies must be strictly increasing")
    gain = np.interp(f, tf, tg)
    outside = (f < tf[0]) | (f > tf[-1])
    return gain, outside


def pressure_per_volt_rows(frequency, table_frequency, table_gain):
    """Gain (Pa/V) by linear interpolation of each point's own table (paper Fig. S1), flat outside it: np.interp row by row.

    ``frequency`` (N, T) Hz; ``table_frequency``, ``table_gain`` (N, K), each row strictly increasing
    (the resolver's check E413).  The arithmetic is np.interp's (slope times offset from the lower
    knot, a knot's own value exactly), so a row equal to the design's table gives the same bits.
    """
    f = np.asarray(frequency, float)
    tf = np.asarray(table_frequency, float)
    tg = np.asarray(table_gain, float)
    k = tf.shape[1]
    if k == 1:
        return np.broadcast_to(tg, f.shape).copy()
    idx = np.clip(np.sum(tf[:, None, :] <= f[:, :, None], axis=2), 1, k - 1)      # upper knot of the interval
    x0, x1 = np.take_along_axis(tf, idx - 1, axis=1), np.take_along_axis(tf, idx, axis=1)
    y0, y1 = np.take_along_axis(tg, idx - 1, axis=1), np.take_along_axis(tg, idx, axis=1)
    inside = (y1 - y0) / (x1 - x0) * (f - x0) + y0
    return np.where(f < tf[:, :1], tg[:, :1], np.where(f >= tf[:, -1:], tg[:, -1:], inside))


def drive_pressure(frequency, voltage, table_frequency, table_gain):
    """Incident pressure amplitude (Pa) for a tone of peak ``voltage`` (linear in V, paper Fig. 2e); returns (pressure, outside_mask)."""
    gain, outside = pressure_per_volt(frequency, table_frequency, table_gain)
    return gain * np.asarray(voltage, float), outside
