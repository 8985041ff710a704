"""The policy part of ``microconveyor demo``: the env's default shipped policy carrying a part to
each of a list of targets (a table: target, rest position, error, firings, outcome), a chart of
the part's position after each firing, one of the errors, and a GIF of one long carry.

On every scene: the line's envs, the positioner (a GIF of one frame per firing: each firing runs
the part to rest) and the plane (targets are points of its grid; the chart draws the part's
path in the plane; a GIF of one frame per firing)."""
from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from microconveyor_env.env_ids import DEFAULT_ENV_ID
from microconveyor_env.envs import EnvConfig
from microconveyor_env.envs.plane.config import PlaneEnvConfig

from ..plots.trajectories import plot_policy_errors, plot_policy_paths
from ..rl.evaluation.evaluate import Policy, load_policy, rollout

GIF_FRAMES_PER_STROKE = 4   # frames per phase of a firing in the GIF: small and still smooth
GIF_FPS = 8.0               # frames per second of the GIF (each phase lasts 1/2 s)
GIF_SHARE = 0.9             # the GIF's default target: this share of the target range's top
FIRING_GIF_FPS = 2.0        # the positioner's and the plane's GIF: one frame per firing
PLANE_POINTS = (1 / 6, 1 / 2, 5 / 6)   # the plane's targets: these shares of the grid's sides


def load_demo_policy(policy_path: str | Path | None = None, config: EnvConfig | None = None,
                     env_id: str = DEFAULT_ENV_ID) -> Policy:
    """The demo's policy (default: the one shipped for ``env_id`` by default,
    :func:`..rl.artefacts.shipped.default_policy_name`) for the scene ``config`` (default:
    ``env_id``'s defaults), loaded before any other work so that a bad ``--policy`` (or one of
    another scene) fails at once."""
    from microconveyor_env.envs.core.versions import scene_config

    from ..rl.artefacts.shipped import require_shipped

    return load_policy(policy_path or require_shipped(env_id), config or scene_config(env_id))


def demo_targets(config: Any) -> list[Any]:
    """The demo's targets [m]. On a line (and the positioner), in ``config``'s target range: its
    low end, then every whole millimetre above it up to the high end (MicroConveyor-v1: 0.5,
    1, 2, ..., 10 mm). On the plane, (x, y) points: the grid box's 3 x 3 points at
    :data:`PLANE_POINTS` of each side, but for one within the tolerance of the start."""
    if isinstance(config, PlaneEnvConfig):
        (x0, x1), (y0, y1) = config.grid_box
        pts = [(x0 + a * (x1 - x0), y0 + b * (y1 - y0)) for b in PLANE_POINTS
               for a in PLANE_POINTS]
        sx, sy = config.start
        return [p for p in pts if np.hypot(p[0] - sx, p[1] - sy) > config.tolerance]
    lo, hi = config.target_range
    mm = np.arange(np.floor(lo * 1e3) + 1, np.floor(hi * 1e3 + 1e-9) + 1)
    return [float(lo)] + [float(m) * 1e-3 for m in mm if m * 1e-3 > lo]


def gif_target(config: Any) -> Any:
    """The GIF's default target [m]: :data:`GIF_SHARE` of the target range's top (9 mm on
    MicroConveyor-v1), a long carry; on the plane the grid box's point at 5/6 of x and 1/6 of
    y, a diagonal carry from the centre."""
    if isinstance(config, PlaneEnvConfig):
        (x0, x1), (y0, y1) = config.grid_box
        return (x0 + PLANE_POINTS[2] * (x1 - x0), y0 + PLANE_POINTS[0] * (y1 - y0))
    return GIF_SHARE * float(config.target_range[1])


def policy_demo(out_dir: str | Path, policy: Policy | str | Path | None = None,
                targets: Sequence[Any] | None = None, config: Any = None,
                gif: Any = None) -> dict[str, Any]:
    """The demo's policy part on ``config`` (default: the default env's), written to
    ``out_dir``: one episode (seed 0, deterministic policy) per target of ``targets`` [m; on the
    plane (x, y) pairs] (default :func:`demo_targets`), the charts ``policy.png`` (position
    after each firing; on the plane the part's paths) and ``policy_errors.png`` (a line's), and
    ``carry.gif``: one episode to ``gif`` [m] (None: no GIF). ``policy``: a loaded
    :class:`~.policy_files.Policy` or a path (default: the shipped one)."""
    from microconveyor_env.envs import env_config

    cfg = config or env_config(DEFAULT_ENV_ID)
    pol = policy if isinstance(policy, Policy) else load_demo_policy(policy, cfg)
    tg = demo_targets(cfg) if targets is None else list(targets)
    out = Path(out_dir)
    name = Path(str(pol.path)).name
    if isinstance(cfg, PlaneEnvConfig):
        rows, paths = _plane_episodes(pol, cfg, tg)
        charts = [_plot_plane_paths(rows, paths, cfg, out / "policy.png",
                                    f"Policy {name}: the part's path to each target")]
    else:
        res = rollout(pol, np.asarray(tg, float), cfg, seed=0, record=True)
        rows = []
        for i, tgt in enumerate(np.asarray(tg, float)):
            err = float(res["error_m"][i])
            rows.append({"target_m": float(tgt), "final_position_m": float(tgt + err),
                         "error_m": err, "time_s": float(res["time_s"][i]),
                         "firings": int(res["firings"][i]), "outcome": str(res["outcome"][i]),
                         "success": bool(res["outcome"][i] == "rest"
                                         and abs(err) <= cfg.tolerance)})
        charts = [plot_policy_paths(res, cfg, out / "policy.png",
                                    title=f"Policy {name}: position after each firing"),
                  plot_policy_errors(rows, cfg.tolerance, out / "policy_errors.png",
                                     title=f"Policy {name}: final error per target")]
    demo: dict[str, Any] = {
        "policy": str(pol.path), "trained_steps": pol.metadata.get("steps"),
        "tolerance_m": cfg.tolerance, "rows": rows,
        "success_rate": float(np.mean([r["success"] for r in rows])) if rows else 0.0,
        "chart": charts[0], "charts": charts, "gif": None}
    if gif is not None:
        writer = carry_gif if type(cfg) is EnvConfig else firing_gif
        demo["gif"] = writer(pol, cfg, gif, out / "carry.gif")
    return demo


def _plane_episodes(policy: Policy, config: PlaneEnvConfig,
                    targets: Sequence[Any]) -> tuple[list[dict[str, Any]], list[np.ndarray]]:
    """One episode of ``policy`` per (x, y) target on the plane (episode ``i`` seeded ``i``,
    as sub-env ``i`` of a batched rollout seeded 0): its row (SI) and the part's path."""
    from microconveyor_env.envs.plane.env import MicroConveyor2DEnv

    env = MicroConveyor2DEnv(config=config)
    rows, paths = [], []
    try:
        for i, (tx, ty) in enumerate(targets):
            obs, _ = env.reset(seed=i, options={"target": (float(tx), float(ty))})
            k = 0
            while True:
                obs, _, term, trunc, info = env.step(np.asarray(policy.act(obs[None]))[0])
                k += 1
                if term or trunc:
                    break
            dist = float(info["distance_m"])
            rows.append({"target_m": [float(tx), float(ty)], "final_position_m": [env.x, env.y],
                         "error_m": dist, "time_s": float(info["sim_time_s"]), "firings": k,
                         "outcome": str(info["outcome"]),
                         "success": bool(info["outcome"] == "rest" and dist <= config.tolerance)})
            paths.append(np.asarray(env.path))
    finally:
        env.close()
    return rows, paths


def _plot_plane_paths(rows: list[dict[str, Any]], paths: list[np.ndarray],
                      config: PlaneEnvConfig, path: Path, title: str) -> str:
    """The part's path in the plane to each target (its position after the reset and each
    firing), the actuators, the targets with their tolerance discs."""
    from ..plots.common import pyplot

    plt = pyplot()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig, ax = plt.subplots(figsize=(6, 5.5))
    act = np.asarray(config.actuator_positions) * 1e3
    ax.plot(act[:, 0], act[:, 1], "^", color="0.7", ms=5, label="actuators")
    tol = config.tolerance * 1e3
    for row, p in zip(rows, paths, strict=True):
        line, = ax.plot(p[:, 0] * 1e3, p[:, 1] * 1e3, ".-", ms=4, lw=1)
        tx, ty = (v * 1e3 for v in row["target_m"])
        ax.add_patch(plt.Circle((tx, ty), tol, color=line.get_color(), alpha=0.3))
        ax.plot(tx, ty, "x", color=line.get_color(),
                mew=1 if row["success"] else 2.5, ms=7)
    ax.set_aspect("equal")
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("y [mm]")
    ax.set_title(f"{title}\n(x: targets, discs ±{config.tolerance * 1e6:.0f} µm, bold: missed)",
                 fontsize=9)
    ax.legend(loc="upper left", fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return str(path)


def firing_gif(policy: Policy, config: Any, target: Any, path: Path) -> dict[str, Any]:
    """One episode of ``policy`` to ``target`` [m; the plane: (x, y)] (seed 0) on the positioner
    or the plane as a GIF at ``path``: one frame after the reset and after each firing
    (:data:`FIRING_GIF_FPS`); its summary (SI units, the file's size in bytes)."""
    from microconveyor_env.envs.core.video import check_writer, write_video
    from microconveyor_env.envs.plane.env import MicroConveyor2DEnv
    from microconveyor_env.envs.positioner.env import MicroPositionerEnv

    check_writer(path)
    plane = isinstance(config, PlaneEnvConfig)
    env: Any = (MicroConveyor2DEnv if plane else MicroPositionerEnv)(
        config=config, render_mode="rgb_array")
    tg: Any = (float(target[0]), float(target[1])) if plane else float(target)
    try:
        obs, _ = env.reset(seed=0, options={"target": tg})
        frames = [np.asarray(env.render())]
        firings = 0
        while True:
            obs, _, term, trunc, info = env.step(np.asarray(policy.act(obs[None]))[0])
            frames.append(np.asarray(env.render()))
            firings += 1
            if term or trunc:
                break
        where: dict[str, Any] = (
            {"target_m": list(tg), "final_position_m": [env.x, env.y],
             "distance_m": float(info["distance_m"])} if plane else
            {"target_m": tg, "final_position_m": env.x,
             "position_error_m": float(info["position_error_m"])})
    finally:
        env.close()
    written = write_video(frames, path, FIRING_GIF_FPS)
    return {"path": str(written), "frames": len(frames), "fps": FIRING_GIF_FPS,
            "bytes": written.stat().st_size, **where, "outcome": str(info["outcome"]),
            "is_success": bool(info["is_success"]), "sim_time_s": float(info["sim_time_s"]),
            "firings": firings}


def carry_gif(policy: Policy, config: EnvConfig, target: Any, path: Path) -> dict[str, Any]:
    """One episode of ``policy`` to ``target`` [m] (seed 0) as a GIF at ``path``: the part on
    the deforming surface, :data:`GIF_FRAMES_PER_STROKE` frames per phase of a firing; its
    summary (SI units, the file's size in bytes)."""
    from microconveyor_env.envs import MicroConveyorEnv
    from microconveyor_env.envs.core.video import check_writer, episode_frames, write_video

    check_writer(path)  # imageio missing: fails before the episode is drawn
    env = MicroConveyorEnv(config=config, render_mode="rgb_array_list",
                           render_frames_per_stroke=GIF_FRAMES_PER_STROKE)
    try:
        frames, episode = episode_frames(
            env, lambda obs: np.asarray(policy.act(obs[None]))[0], float(target), seed=0)
    finally:
        env.close()
    written = write_video(frames, path, GIF_FPS)
    return {"path": str(written), "frames": len(frames), "fps": GIF_FPS,
            "bytes": written.stat().st_size, **episode}


def _mm(v: Any) -> str:
    """A position [m] in mm: one number, or (x, y)."""
    if isinstance(v, (list, tuple)):
        return f"({v[0] * 1e3:.3f}, {v[1] * 1e3:.3f})"
    return f"{v * 1e3:.3f}"


def policy_table(demo: dict[str, Any]) -> str:
    """The policy's episodes of the demo, one line per target, in the units people read (on the
    plane: (x, y) in mm and the distance to the target)."""
    steps = demo["trained_steps"]
    tol_um = demo["tolerance_m"] * 1e6
    plane = bool(demo["rows"]) and isinstance(demo["rows"][0]["target_m"], list)
    width = 16 if plane else 11
    err_head = f"{'distance [µm]':>13}" if plane else f"{'error [µm]':>10}"
    lines = [f"policy {demo['policy']}" + (f" ({steps:,} steps)" if steps else ""),
             f"{'target [mm]':>{width}} {'rest position [mm]':>18} {err_head} "
             f"{'firings':>7}  outcome (success: at rest within ±{tol_um:.0f} µm)"]
    for r in demo["rows"]:
        outcome = "success" if r["success"] else (
            "miss" if r["outcome"] == "rest" else f"{r['outcome']} (not at rest)")
        err = f"{r['error_m'] * 1e6:13.1f}" if plane else f"{r['error_m'] * 1e6:+10.1f}"
        lines.append(f"{_mm(r['target_m']):>{width}} {_mm(r['final_position_m']):>18} {err} "
                     f"{r['firings']:7d}  {outcome}")
    lines.append(f"{sum(r['success'] for r in demo['rows'])} of {len(demo['rows'])} targets "
                 f"within ±{tol_um:.0f} µm")
    g = demo.get("gif")
    if g:
        miss = (f"distance {g['distance_m'] * 1e6:.1f} µm" if "distance_m" in g else
                f"error {g['position_error_m'] * 1e6:+.1f} µm")
        lines.append(f"wrote {g['path']}: a carry to {_mm(g['target_m'])} mm, "
                     f"{g['outcome']} at {_mm(g['final_position_m'])} mm ({miss}) after "
                     f"{g['firings']} firing(s); {g['frames']} frames, {g['bytes'] / 1024:.0f} kB")
    return "\n".join(lines)
