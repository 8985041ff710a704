"""rgb_array frames of MicroConveyor2D-v0 (matplotlib Agg, imported lazily): a top view of the
grid with the surface's height map at the last firing's peak stroke, the part's path, the part and
the target with its tolerance disc."""
from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from ...physics.plane.kinematics import plane_surface_height

if TYPE_CHECKING:
    from .config import PlaneEnvConfig

FRAME_SIZE = (6.0, 5.0)  # inches
FRAME_DPI = 80           # -> 480 x 400 pixels


def render_plane_frame(cfg: PlaneEnvConfig, path: Sequence[tuple[float, float]],
                       target: tuple[float, float], fired: int,
                       last_firing: tuple[int, float, float, float] | None, t: float,
                       size: tuple[float, float] = FRAME_SIZE, dpi: int = FRAME_DPI) -> np.ndarray:
    """uint8 (H, W, 3): the frame of a state. ``path``: the part's positions [m] since the reset
    (the last one is the part now); ``last_firing``: (actuator, f [Hz], h [m], delay [s]) of the
    last step, whose bump at its peak h is drawn as a height map with contours (the plane is flat
    between firings), or None."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.patches import Circle

    pos = np.asarray(cfg.actuator_positions).reshape(-1, 2)
    pts = np.asarray(path, dtype=float).reshape(-1, 2)
    span = cfg.wavelength / 4
    lo = np.minimum(pos.min(0), np.minimum(pts.min(0), target)) - span
    hi = np.maximum(pos.max(0), np.maximum(pts.max(0), target)) + span
    fig = Figure(figsize=size, dpi=dpi)
    canvas = FigureCanvasAgg(fig)
    ax = fig.add_subplot(111)
    xs, ys = np.linspace(lo[0], hi[0], 160), np.linspace(lo[1], hi[1], 160)
    gx, gy = np.meshgrid(xs, ys)
    if last_firing is not None:
        j, f, h, _ = last_firing
        z = plane_surface_height(gx, gy, h, cfg.shape, cfg.wavelength, *pos[j]) * 1e6
        im = ax.pcolormesh(gx * 1e3, gy * 1e3, z, cmap="Oranges", shading="auto", vmin=0.0,
                           vmax=cfg.stroke_range[1] * 1e6)
        ax.contour(gx * 1e3, gy * 1e3, z, levels=5, colors="0.4", linewidths=0.6)
        fig.colorbar(im, ax=ax, label=f"peak height [µm] ({f:.0f} Hz, {h * 1e6:.0f} µm)")
        ax.plot(*(pos[j] * 1e3), marker="*", ms=14, color="tab:orange", mec="k", ls="",
                label=f"fired: actuator {j}")
    ax.plot(pos[:, 0] * 1e3, pos[:, 1] * 1e3, "^", ms=6, color="tab:blue", ls="",
            label="actuators")
    ax.add_patch(Circle((target[0] * 1e3, target[1] * 1e3), cfg.tolerance * 1e3,
                        color="tab:green", alpha=0.35))
    ax.plot([target[0] * 1e3], [target[1] * 1e3], "x", ms=9, color="tab:green", label="target")
    ax.plot(pts[:, 0] * 1e3, pts[:, 1] * 1e3, "-o", ms=3, lw=1, color="0.2", label="part's path")
    ax.plot([pts[-1, 0] * 1e3], [pts[-1, 1] * 1e3], "s", ms=8, color="tab:red", label="part")
    ax.set_xlim(lo[0] * 1e3, hi[0] * 1e3)
    ax.set_ylim(lo[1] * 1e3, hi[1] * 1e3)
    ax.set_aspect("equal")
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("y [mm]")
    err = float(np.hypot(*(pts[-1] - np.asarray(target))))
    ax.set_title(f"t = {t * 1e3:.2f} ms, fired {fired}/{cfg.max_firings}, "
                 f"error {err * 1e6:.0f} µm", fontsize=9)
    ax.legend(fontsize=6, loc="upper left", framealpha=0.7)
    fig.tight_layout()
    canvas.draw()
    return np.asarray(canvas.buffer_rgba())[:, :, :3].copy()
