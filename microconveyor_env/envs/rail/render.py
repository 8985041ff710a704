"""rgb_array frames of a rail (matplotlib Agg, imported lazily): one frame of a state after a
step (:func:`render_frame`; the line's and the positioner's) and the frames during a firing
(:class:`FrameDrawer`, states from the line's :mod:`..line.frames`)."""
from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from .config import RailConfig

import numpy as np

from ...physics.kinematics import surface_profile


def render_frame(cfg: RailConfig, x: float, target: float, fired: int,
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


class FrameDrawer:
    """Frames of :class:`~.frames.FrameState` s (uint8 (H, W, 3)): one matplotlib figure kept and
    updated (~4x faster than a new figure per frame). The view spans the actuators, the target
    and the part, and widens (never narrows) within an episode when the part leaves it."""

    def __init__(self, cfg: RailConfig, size: tuple = (8.0, 3.0), dpi: int = 80) -> None:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
        from matplotlib.patches import Rectangle

        self.cfg = cfg
        self.pos = np.asarray(cfg.actuator_positions)
        self.fig = Figure(figsize=size, dpi=dpi)
        self.canvas = FigureCanvasAgg(self.fig)
        ax = self.ax = self.fig.add_subplot(111)
        self.view = (np.nan, np.nan, np.nan)  # (target, lo, hi) [m]
        ax.axhline(0.0, color="0.75", lw=1)
        (self.surface,) = ax.plot([], [], color="0.3", lw=2, label="surface")
        self.actuators = ax.scatter(self.pos * 1e3, np.full(self.pos.size, -25.0), marker="^",
                                    s=80)
        # the tolerance band: x in data units, y over the whole axes (a Rectangle whatever the
        # matplotlib version; axvspan returns a Polygon before 3.9)
        self.band = Rectangle((0.0, 0.0), 0.0, 1.0, transform=ax.get_xaxis_transform(),
                              color="tab:green", alpha=0.25, label="target ± tolerance")
        ax.add_patch(self.band)
        self.target_line = ax.axvline(0.0, color="tab:green", lw=1)
        (self.part,) = ax.plot([], [], "s", ms=9, color="tab:red", label="part")
        ax.set_ylim(-60, max(260.0, cfg.stroke_range[1] * 1e6 + 60.0))
        ax.set_xlabel("x [mm]")
        ax.set_ylabel("height [µm]")
        self.title = ax.set_title(" ", fontsize=9)
        ax.legend(fontsize=7, loc="upper right")
        self.fig.tight_layout()

    def _set_view(self, x: float, target: float) -> None:
        t0, lo, hi = self.view
        if target != t0:  # a new episode: the view of its scene
            lo = min(self.pos[0], target, x) - 1.0e-3
            hi = max(self.pos[-1], target, x) + 1.0e-3
        elif lo + 0.2e-3 <= x <= hi - 0.2e-3:
            return
        else:
            lo, hi = min(lo, x - 1.0e-3), max(hi, x + 1.0e-3)
        self.view = (target, lo, hi)
        self.xs = np.linspace(lo, hi, 800)
        self.ax.set_xlim(lo * 1e3, hi * 1e3)
        tol = self.cfg.tolerance
        self.band.set_x((target - tol) * 1e3)
        self.band.set_width(2 * tol * 1e3)
        self.target_line.set_xdata([target * 1e3, target * 1e3])

    def draw(self, s: Any) -> np.ndarray:
        """The frame of state ``s`` (a :class:`~.frames.FrameState`)."""
        cfg = self.cfg
        self._set_view(s.x, s.target)
        ys = np.zeros_like(self.xs)
        y_part = 0.0
        if s.amplitude != 0.0:
            ys = surface_profile(self.xs, s.amplitude, cfg.shape, cfg.wavelength, s.xa)
            y_part = float(surface_profile(np.array([s.x]), s.amplitude, cfg.shape,
                                           cfg.wavelength, s.xa)[0])
        self.surface.set_data(self.xs * 1e3, ys * 1e6)
        self.surface.set_color("tab:orange" if s.amplitude != 0.0 else "0.3")
        self.part.set_data([s.x * 1e3], [y_part * 1e6 + 25.0])  # the part rests on the surface
        colors = ["tab:orange" if i == s.firing else ("0.6" if i < s.fired else "tab:blue")
                  for i in range(self.pos.size)]
        self.actuators.set_color(colors)
        self.title.set_text(f"t = {s.t * 1e3:.3f} ms, {s.label}, error "
                            f"{abs(s.x - s.target) * 1e6:.0f} µm")
        self.canvas.draw()
        return np.asarray(self.canvas.buffer_rgba())[:, :, :3].copy()
