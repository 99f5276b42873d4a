"""The force engine of :mod:`acl.analysis.acoustics` under many drives at once (issue 23: one engine, batched).

* :func:`tone_engine` -- the engine of a design at a set of tones (each at 1 V), cached;
* :func:`drive_factors`, :func:`drive_constants` -- what a row's own tone amplitudes, transducer gain table (a
  draw of a band) and thrust scale change in the engine's constants;
* :func:`force_batch_tones` -- :func:`acl.analysis.acoustics.force_model` for B configurations, each under its own
  drive: one vectorised evaluation (the re-simulation of a schedule and its band's draws);
* :func:`tone_forces` -- the force of each tone alone at one configuration (gain tables, latch forces), the
  coupled response solved once.

The physics is the engine's (:meth:`acl.analysis.acoustics._Engine.forces`: thrust, Bjerknes, jet drag); this module
only feeds it per-row constants.
"""
from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np

from acl.analysis.acoustics import (_apply_neighbour_drag, _centres_array, _compute_engine, _Engine,
                                    _thrust_scale, drive_gain, effect_pressure_factor, pressure_terms,
                                    substrate_factor)
from acl.analysis.environment import medium_constants
from acl.design.model import Design, Drive, Tone
from acl.physics import constants as C
from acl.physics.coupling import coupled_volumes

_TONE_ENGINES: list = []   # [(design, frequencies, engine)]: the tone engines of the last designs


def tone_engine(design: Design, frequencies) -> _Engine:
    """The force engine of ``design`` at the tones ``frequencies`` (Hz), each at 1 V (cached per design identity and
    tones): :meth:`_Engine.forces` with :func:`drive_constants` evaluates any amplitudes of those tones."""
    f = tuple(float(x) for x in frequencies)
    for d, ff, eng in _TONE_ENGINES:
        if d is design and ff == f:
            return eng
    eng = _compute_engine(design, Drive(tones=tuple(Tone(frequency=x, amplitude=1.0) for x in f)))
    _TONE_ENGINES[:] = ([(design, f, eng)] + _TONE_ENGINES)[:8]
    return eng


def drive_factors(design: Design, frequencies) -> tuple[np.ndarray, np.ndarray]:
    """(gain (T,) Pa/V at the tones, thrust scale (C,)) of ``design``: what a draw of its transducer gain table changes
    in the force engine (the declared thrust coefficient is matched through the gain, :func:`_thrust_scale`)."""
    f = np.asarray(frequencies, float)
    gain, _ = drive_gain(design, f) if f.size else (np.zeros(0), None)
    caps = design.capsules                   # _layout's order (a band's draws would each rebuild the layout)
    sub = np.array([substrate_factor(design, c) for c in caps]) if design.effects else np.ones(len(caps))
    return np.asarray(gain, float), np.array([_thrust_scale(design, c) for c in caps]) * sub


def drive_constants(eng: _Engine, amplitudes: np.ndarray, gain: np.ndarray, scale: np.ndarray) -> dict:
    """Per-row drive constants of :meth:`_Engine.forces` for tone amplitudes (B, T) V, gains (B, T) Pa/V and thrust
    scales (B, C) (:func:`drive_factors`): the same pressure (amplitude x gain x effects, drive saturation at each
    row's total amplitude) and constants as :func:`_compute_engine` builds for one drive."""
    v = np.asarray(amplitudes, float)
    pressure = v * gain * effect_pressure_factor(eng.design, eng.f, v.sum(axis=1, keepdims=True))
    thrust, w2p2 = pressure_terms(eng.consts["thrust_unit"], eng.consts["w2"], pressure, scale[:, eng.lay.body])
    return {"thrust": thrust, "w2p2": w2p2}


def tone_forces(design: Design, frequencies, positions: Mapping[str, Sequence[float]] | None = None,
                block: int = 64) -> np.ndarray:
    """Acoustic force (F, C, 3) N on each capsule of each tone alone at 1 V: :func:`force_model` of every single-tone
    drive (tones add in power), the capsules at rest or at ``positions``, the coupled response solved once."""
    f = np.atleast_1d(np.asarray(frequencies, float))
    eng = tone_engine(design, f)
    lay = eng.lay
    ncap = len(lay.caps)
    out = np.zeros((f.size, ncap, 3))
    if f.size == 0:
        return out
    centres = _centres_array(design, positions) if positions else lay.rest
    r = eng.response((centres[lay.body] + lay.offsets)[None]) if lay.radii.size else np.zeros((1, f.size, 0), complex)
    gain, scale = drive_factors(design, f)
    for t0 in range(0, f.size, block):
        rows = np.arange(t0, min(t0 + block, f.size))
        b = rows.size
        amp = np.zeros((b, f.size))
        amp[np.arange(b), rows] = 1.0
        resp = np.zeros((b, f.size, r.shape[2]), complex)
        resp[np.arange(b), rows] = r[0, rows]
        at = np.broadcast_to(centres, (b, ncap, 3))
        consts = drive_constants(eng, amp, np.broadcast_to(gain, (b, f.size)), np.broadcast_to(scale, (b, ncap)))
        out[rows] = _apply_neighbour_drag(design, lay, at, eng.forces(at, consts=consts, response=resp))
    return out


def force_batch_tones(design: Design, centres: np.ndarray, frequencies, amplitudes: np.ndarray,
                      gain: np.ndarray | None = None, scale: np.ndarray | None = None) -> np.ndarray:
    """:func:`force_model` for configurations (B, C, 3) each under its own amplitudes (B, T) V of the tones
    ``frequencies``, and optionally its own gains (B, T) Pa/V and thrust scales (B, C) (:func:`drive_factors` of a
    draw of the gain table): forces (B, C, 3).  Row b equals force_model at row b's drive."""
    eng = tone_engine(design, frequencies)
    centres = np.asarray(centres, float)
    nb = centres.shape[0]
    if gain is None or scale is None:
        g0, s0 = drive_factors(design, eng.f)
        gain = np.broadcast_to(g0, (nb, eng.f.size)) if gain is None else gain
        scale = np.broadcast_to(s0, (nb, len(eng.lay.caps))) if scale is None else scale
    consts = drive_constants(eng, amplitudes, np.asarray(gain, float), np.asarray(scale, float))
    return _apply_neighbour_drag(design, eng.lay, centres, eng.forces(centres, consts=consts))


_ONE_TONE: list = []       # [(design, frequencies, stacked single-tone engine data)]: the last designs


def _one_tone_stack(design: Design, frequencies) -> tuple:
    """(first engine, f (F,), thrust per unit volume (F, 1, n), w^2 (F, 1), uncoupled blocks (F, 1, C, P, P)) of the
    single-tone engines (:func:`tone_engine` of each tone alone), stacked; cached per design identity and tones."""
    key = tuple(float(x) for x in frequencies)
    for d, k, hit in _ONE_TONE:
        if d is design and k == key:
            return hit
    engines = [tone_engine(design, [f]) for f in key]
    hit = (engines[0], np.array([e.f[0] for e in engines]), np.stack([e.consts["thrust_unit"] for e in engines]),
           np.stack([e.consts["w2"] for e in engines]),
           np.stack([e.h0 for e in engines]) if engines[0].h0 is not None else None)
    _ONE_TONE[:] = ([(design, key, hit)] + _ONE_TONE)[:4]
    return hit


def force_rows_one_tone(design: Design, centres: np.ndarray, frequencies, tone: np.ndarray, amplitude: np.ndarray,
                        gain: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """:func:`force_batch_tones` of rows that each play one tone alone: row b at tone ``frequencies[tone[b]]`` with
    amplitude ``amplitude[b]`` V, gain ``gain[b]`` Pa/V there and thrust scales ``scale[b]`` (C,): forces (B, C, 3).

    Row b is the same computation as :func:`force_batch_tones` of the single-tone engine of its tone (its uncoupled
    blocks and constants; the coupled response solved with its own frequency as a batch axis): one evaluation for
    rows at different tones (the band cure's single-tone readings, acl.schedule.experiment)."""
    eng, fs, units, w2s, blocks = _one_tone_stack(design, frequencies)
    lay = eng.lay
    centres = np.asarray(centres, float)
    tone = np.asarray(tone, int)
    f = fs[tone][:, None]                                                           # (B, 1)
    v = np.asarray(amplitude, float).reshape(-1, 1)
    pressure = v * np.asarray(gain, float).reshape(-1, 1) * effect_pressure_factor(design, f, v.sum(axis=1, keepdims=True))
    thrust, w2p2 = pressure_terms(units[tone], w2s[tone], pressure, np.asarray(scale, float)[:, lay.body])
    if blocks is not None and lay.radii.size:
        med = medium_constants(design)
        r = coupled_volumes(blocks[tone], eng.system.slot, centres[:, lay.body, :] + lay.offsets, eng.system.radii, f,
                            med.density, med.sound_speed, C.SUBSTRATE_REFLECTION)          # (B, 1, n) per pascal
    else:
        r = np.zeros((centres.shape[0], 1, lay.radii.size), complex)
    return _apply_neighbour_drag(design, lay, centres, eng.forces(centres, consts={"thrust": thrust, "w2p2": w2p2},
                                                                    response=r))
