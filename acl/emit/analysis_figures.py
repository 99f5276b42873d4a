"""PNG figures of an analysis (matplotlib, imported only here): modal response (as paper Fig. 3b),
pair amplitude and phase with attract/repel bands (Fig. 4f), gap vs voltage with snap-in (Fig. 4e),
latch energy landscapes (Fig. 6d). Each file is written to a temporary name and renamed."""
from __future__ import annotations

import os
import tempfile

import numpy as np


def _save(fig, path: str) -> str:
    from acl._files import as_umask

    fd, tmp = tempfile.mkstemp(prefix=".tmp-", suffix=".png", dir=os.path.dirname(path) or ".")
    os.close(fd)
    try:
        as_umask(tmp, directory=False)
        fig.savefig(tmp, dpi=120, bbox_inches="tight")
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    return path


def write_figures(design, rep, outdir: str) -> list[str]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from acl.analysis import acoustics as AC
    from acl.analysis import mechanics as ME
    from acl.design import model as M
    from acl.physics import latch as LT

    os.makedirs(outdir, exist_ok=True)
    written = []
    # the responses per pascal, over the transducer's band: per volt they carried the kinks of the gain table's
    # linear interpolation (acoustics.drive_gain) and ran beyond the band (modal response and pair figures alike)
    t = design.transducer
    fm = np.linspace(*t.band, 600) if t is not None else np.linspace(20e3, 250e3, 600)
    per_pa = t is not None and len(t.gain_frequencies) > 0
    g = np.asarray(AC.drive_gain(design, fm)[0], float) if design.capsules else np.ones_like(fm)
    unit = "per pascal (um^3/Pa)" if per_pa else "per volt (um^3/V)"
    # 1. modal response of each capsule (paper Fig. 3b)
    if design.capsules:
        fig, ax = plt.subplots(figsize=(7, 4))
        for c in design.capsules:
            h = np.abs(AC.orifice_response(design, c, fm))
            if per_pa:
                h = h / np.maximum(g, 1e-300)[:, None]
            for k, o in enumerate(c.orifices):
                ax.semilogy(fm / 1e3, h[:, k] * 1e18, label=f"{c.name}.{o.name}")
            for m in AC.capsule_modes(design, c):
                if fm[0] <= m.frequency_hz <= fm[-1]:
                    ax.axvline(m.frequency_hz / 1e3, ls="--", lw=0.6, color="grey")
        ax.set_xlim(fm[0] / 1e3, fm[-1] / 1e3)
        ax.set_xlabel("frequency (kHz)")
        ax.set_ylabel(f"volume amplitude {unit}")
        ax.set_title("Modal response (cf. paper Fig. 3b)")
        ax.legend(fontsize=7)
        written.append(_save(fig, os.path.join(outdir, "modal_response.png")))
        plt.close(fig)
    # 2. amplitude and phase of every pair with attract/repel bands (Fig. 4f)
    caps = list(design.capsules)
    for i, a in enumerate(caps):
        for b in caps[i + 1:]:
            f = fm
            ha = AC.orifice_response(design, a, f)[:, 0]
            hb = AC.orifice_response(design, b, f)[:, 0]
            dphi = np.degrees(np.angle(ha * np.conj(hb)))
            fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(7, 5), sharex=True)
            scale = 1e18 / (np.maximum(g, 1e-300) if per_pa else 1.0)
            ax1.semilogy(f / 1e3, np.abs(ha) * scale, label=a.name)
            ax1.semilogy(f / 1e3, np.abs(hb) * scale, ls="--", label=b.name)     # dashed: an equal pair shows both
            ax1.set_ylabel(f"|dV| {unit}")
            ax1.set_xlim(f[0] / 1e3, f[-1] / 1e3)
            ax1.legend(fontsize=7)
            ax2.plot(f / 1e3, np.degrees(np.angle(ha)), label=f"phase {a.name}")
            ax2.plot(f / 1e3, np.degrees(np.angle(hb)), ls="--", label=f"phase {b.name}")
            ax2.plot(f / 1e3, dphi, label="difference", color="k")
            rep_band = np.abs(dphi) > 90
            ax2.fill_between(f / 1e3, -180, 180, where=rep_band, color="grey", alpha=0.3, label="repel")
            ax2.set_ylim(-180, 180)
            ax2.set_xlabel("frequency (kHz)")
            ax2.set_ylabel("phase (deg)")
            ax2.legend(fontsize=7)
            fig.suptitle(f"{a.name} - {b.name}: attract where |phase difference| < 90 deg (cf. Fig. 4f)")
            written.append(_save(fig, os.path.join(outdir, f"pair_{a.name}_{b.name}.png")))
            plt.close(fig)
    # 3. gap vs voltage with snap-in (Fig. 4e), at each program frequency
    vmax = design.transducer.max_voltage if design.transducer else 20.0
    for fr in rep.frequencies_hz[:4]:
        if len(caps) < 2:
            break
        sw = ME.sweep_voltage(design, M.Drive(tones=(M.Tone(frequency=fr, amplitude=1.0),)), vmax, AC.force_model_for(design))
        fig, ax = plt.subplots(figsize=(6, 4))
        for i, a in enumerate(caps):
            for b in caps[i + 1:]:
                ax.plot(sw.voltage, sw.gap(design, a.name, b.name) * 1e6, label=f"{a.name}-{b.name}")
        if sw.snap_voltage is not None:
            ax.axvline(sw.snap_voltage, color="r", ls="--", label=f"snap-in {sw.snap_voltage:.2f} V")
        ax.set_xlabel("voltage (V)")
        ax.set_ylabel("gap (um)")
        ax.set_title(f"Equilibrium gap at {fr / 1e3:g} kHz (cf. Fig. 4e)")
        ax.legend(fontsize=7)
        written.append(_save(fig, os.path.join(outdir, f"gap_vs_voltage_{fr / 1e3:g}kHz.png")))
        plt.close(fig)
    # 4. latch energy landscapes (Fig. 6d)
    if design.latches:
        fig, ax = plt.subplots(figsize=(6, 4))
        for lt in design.latches:
            land = LT.latch_landscape(lt.angle, lt.length, lt.width, lt.thickness, lt.youngs_modulus)
            ax.plot(np.asarray(land.u) * 1e6, np.asarray(land.energy) * 1e15, label=f"{lt.name} ({np.degrees(lt.angle):.0f} deg)")
        ax.set_xlabel("shuttle travel (um)")
        ax.set_ylabel("strain energy (fJ)")
        ax.set_title("Latch energy landscapes (cf. Fig. 6d)")
        ax.legend(fontsize=7)
        written.append(_save(fig, os.path.join(outdir, "latch_landscapes.png")))
        plt.close(fig)
    return written
