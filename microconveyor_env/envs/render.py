"""rgb_array frames of the conveyor (matplotlib Agg, imported lazily)."""
from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from .config import EnvConfig

import numpy as np

from ..physics.kinematics import surface_profile


def render_frame(cfg: EnvConfig, x: float, target: float, fired: int,
                 last_firing: tuple | None, t: float, size: tuple = (8.0, 3.0),
                 dpi: int = 80) -> np.ndarray:
    """uint8 (H, W, 3): surface, actuators, part, target and tolerance band.

    The last firing's peak deformation is drawn dashed (the surface is flat between strokes).
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    pos = np.asarray(cfg.actuator_positions)
    lo = min(pos[0], x, target) - 1.0e-3
    hi = max(pos[-1], x, target) + 1.0e-3
    xs = np.linspace(lo, hi, 600)
    fig = Figure(figsize=size, dpi=dpi)
    canvas = FigureCanvasAgg(fig)
    ax = fig.add_subplot(111)
    ax.axhline(0.0, color="0.3", lw=2)
    if last_firing is not None:
        xa, f, h, d = last_firing
        ax.plot(xs * 1e3, surface_profile(xs, h, cfg.shape, cfg.wavelength, xa) * 1e6, "--",
                color="tab:orange", lw=1, label=f"last stroke peak ({f:.0f} Hz, {h * 1e6:.0f} µm)")
    for i, p in enumerate(pos):
        ax.plot([p * 1e3], [-25], marker="^", ms=10, color="tab:blue" if i >= fired else "0.6")
    ax.axvspan((target - cfg.tolerance) * 1e3, (target + cfg.tolerance) * 1e3, color="tab:green",
               alpha=0.25, label="target +- tolerance")
    ax.axvline(target * 1e3, color="tab:green", lw=1)
    ax.plot([x * 1e3], [25], "s", ms=9, color="tab:red", label="part")
    ax.set_xlim(lo * 1e3, hi * 1e3)
    ax.set_ylim(-60, 260)
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("height [µm]")
    ax.set_title(f"t = {t * 1e3:.2f} ms, fired {fired}/{cfg.n_actuators}, "
                 f"error {abs(x - target) * 1e6:.0f} µm", fontsize=9)
    ax.legend(fontsize=7, loc="upper right")
    fig.tight_layout()
    canvas.draw()
    return np.asarray(canvas.buffer_rgba())[:, :, :3].copy()
