"""The policy part of ``microconveyor demo``: the env's default shipped policy carrying a part to
each of a list of targets (a table: target, rest position, error, firings, outcome), a chart of
the part's position after each firing, one of the errors, and a GIF of one long carry."""
from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from microconveyor_env.env_ids import DEFAULT_ENV_ID
from microconveyor_env.envs import EnvConfig

from ..plots.trajectories import plot_policy_errors, plot_policy_paths
from ..rl.evaluation.evaluate import Policy, load_policy, rollout

GIF_FRAMES_PER_STROKE = 4   # frames per phase of a firing in the GIF: small and still smooth
GIF_FPS = 8.0               # frames per second of the GIF (each phase lasts 1/2 s)
GIF_SHARE = 0.9             # the GIF's default target: this share of the target range's top


def load_demo_policy(policy_path: str | Path | None = None, config: EnvConfig | None = None,
                     env_id: str = DEFAULT_ENV_ID) -> Policy:
    """The demo's policy (default: the one shipped for ``env_id`` by default,
    :func:`..rl.artefacts.shipped.default_policy_name`) for the scene ``config`` (default:
    ``env_id``'s defaults), loaded before any other work so that a bad ``--policy`` (or one of
    another scene) fails at once."""
    from microconveyor_env.envs import env_config

    from ..rl.artefacts.shipped import require_shipped

    return load_policy(policy_path or require_shipped(env_id), config or env_config(env_id))


def demo_targets(config: EnvConfig) -> list[float]:
    """The demo's targets [m] in ``config``'s target range: its low end, then every whole
    millimetre above it up to the high end (MicroConveyor-v1: 0.5, 1, 2, ..., 10 mm)."""
    lo, hi = config.target_range
    mm = np.arange(np.floor(lo * 1e3) + 1, np.floor(hi * 1e3 + 1e-9) + 1)
    return [float(lo)] + [float(m) * 1e-3 for m in mm if m * 1e-3 > lo]


def gif_target(config: EnvConfig) -> float:
    """The GIF's default target [m]: :data:`GIF_SHARE` of the target range's top (9 mm on
    MicroConveyor-v1), a long carry."""
    return GIF_SHARE * float(config.target_range[1])


def policy_demo(out_dir: str | Path, policy: Policy | str | Path | None = None,
                targets: Sequence[float] | None = None, config: EnvConfig | None = None,
                gif: float | None = None) -> dict[str, Any]:
    """The demo's policy part on ``config`` (default: the default env's), written to
    ``out_dir``: one episode (seed 0, deterministic policy) per target of ``targets`` [m]
    (default :func:`demo_targets`), the charts ``policy.png`` (position after each firing) and
    ``policy_errors.png``, and ``carry.gif``: one episode to ``gif`` [m] (None: no GIF).
    ``policy``: a loaded :class:`~.policy_files.Policy` or a path (default: the shipped one)."""
    from microconveyor_env.envs import env_config

    cfg = config or env_config(DEFAULT_ENV_ID)
    pol = policy if isinstance(policy, Policy) else load_demo_policy(policy, cfg)
    tg = np.asarray(demo_targets(cfg) if targets is None else targets, float)
    res = rollout(pol, tg, cfg, seed=0, record=True)
    rows = []
    for i, tgt in enumerate(tg):
        err = float(res["error_m"][i])
        rows.append({"target_m": float(tgt), "final_position_m": float(tgt + err),
                     "error_m": err, "time_s": float(res["time_s"][i]),
                     "firings": int(res["firings"][i]), "outcome": str(res["outcome"][i]),
                     "success": bool(res["outcome"][i] == "rest" and abs(err) <= cfg.tolerance)})
    out = Path(out_dir)
    name = Path(str(pol.path)).name
    charts = [plot_policy_paths(res, cfg, out / "policy.png",
                                title=f"Policy {name}: position after each firing"),
              plot_policy_errors(rows, cfg.tolerance, out / "policy_errors.png",
                                 title=f"Policy {name}: final error per target")]
    demo: dict[str, Any] = {
        "policy": str(pol.path), "trained_steps": pol.metadata.get("steps"),
        "tolerance_m": cfg.tolerance, "rows": rows,
        "success_rate": float(np.mean([r["success"] for r in rows])),
        "chart": charts[0], "charts": charts, "gif": None}
    if gif is not None:
        demo["gif"] = carry_gif(pol, cfg, float(gif), out / "carry.gif")
    return demo


def carry_gif(policy: Policy, config: EnvConfig, target: float, path: Path) -> dict[str, Any]:
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
            env, lambda obs: np.asarray(policy.act(obs[None]))[0], target, seed=0)
    finally:
        env.close()
    written = write_video(frames, path, GIF_FPS)
    return {"path": str(written), "frames": len(frames), "fps": GIF_FPS,
            "bytes": written.stat().st_size, **episode}


def policy_table(demo: dict[str, Any]) -> str:
    """The policy's episodes of the demo, one line per target, in the units people read."""
    steps = demo["trained_steps"]
    tol_um = demo["tolerance_m"] * 1e6
    lines = [f"policy {demo['policy']}" + (f" ({steps:,} steps)" if steps else ""),
             f"{'target [mm]':>11} {'rest position [mm]':>18} {'error [µm]':>10} "
             f"{'firings':>7}  outcome (success: at rest within ±{tol_um:.0f} µm)"]
    for r in demo["rows"]:
        outcome = "success" if r["success"] else (
            "miss" if r["outcome"] == "rest" else f"{r['outcome']} (not at rest)")
        lines.append(f"{r['target_m'] * 1e3:11.3f} {r['final_position_m'] * 1e3:18.3f} "
                     f"{r['error_m'] * 1e6:+10.1f} {r['firings']:7d}  {outcome}")
    lines.append(f"{sum(r['success'] for r in demo['rows'])} of {len(demo['rows'])} targets "
                 f"within ±{tol_um:.0f} µm")
    g = demo.get("gif")
    if g:
        lines.append(f"wrote {g['path']}: a carry to {g['target_m'] * 1e3:.3f} mm, "
                     f"{g['outcome']} at {g['final_position_m'] * 1e3:.3f} mm (error "
                     f"{g['position_error_m'] * 1e6:+.1f} µm) after {g['firings']} firing(s); "
                     f"{g['frames']} frames, {g['bytes'] / 1024:.0f} kB")
    return "\n".join(lines)
