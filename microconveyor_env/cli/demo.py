"""The physics and env part of ``microconveyor demo`` (the command: :mod:`agents.cli.demo`, which
adds the shipped policy): a contact report, a firing, a frequency sweep and an env episode of a
fixed schedule, charts and a summary in ``--out``."""
from __future__ import annotations

import json

from ..env_ids import DEFAULT_ENV_ID
from .base import json_default


def demo_text(summary: dict) -> str:
    """The demo's figures in the units people read, then the files it wrote."""
    from .human import format_value

    def show(key: str, v: object) -> str:
        return format_value(key, v)[1]

    c, f, e = summary["contact"], summary["reference_firing"], summary["episode"]
    window = summary["window_hz"]
    lines = [f"preset {summary['preset']}: pull-off {show('f_N', c['pull_off_force_N'])}, "
             f"friction at weight {show('f_N', c['friction_at_weight_N'])}",
             f"reference firing (950 Hz, 200 µm): travel {show('d_m', f['displacement_m'])}, "
             f"{f['outcome']}",
             "feasible window: " + (f"{show('w_hz', window[0])} to {show('w_hz', window[1])}"
                                    if window else "none"),
             f"{e['env_id']} episode, a fixed schedule ({e.get('schedule', 'to 1 mm')}): "
             f"{e['outcome']}, {'distance' if 'distance_m' in e else 'error'} "
             f"{show('e_m', e.get('error_m', e['position_error_m']))}"]
    lines += [f"wrote {c}" for c in summary["charts"] + [summary["summary_json"]]]
    return "\n".join(lines)


def demo_summary(args) -> dict:
    """Run the demo into ``args.out``; the summary (also written to ``summary.json``)."""
    from pathlib import Path

    from ..physics.contact_table import ContactTable
    from ..plots import plot_contact, plot_firing, plot_sweep
    from ..presets import load_preset
    from ..studies.sweep import Scene, parse_values, sweep

    out_dir = Path(args.out)
    out_dir.mkdir(parents=True, exist_ok=True)
    preset = load_preset(args.preset)
    table = ContactTable(preset.contact)
    charts = [plot_contact(table, out_dir / "contact.png", f"preset {preset.name}")]
    scene = Scene(preset=args.preset)
    # the chart's firing with a 10x finer step than the default, so the curves are smooth; run
    # once first so the reported wall time is the steady-state figure, not the numba compile
    fine = Scene(preset=args.preset, sim_kw={"dt": 5e-6})
    fine.run()
    firing = fine.run(record=True)
    charts.append(plot_firing(firing, scene.freq, out_dir / "firing.png", stroke=scene.stroke))
    freq = sweep(scene, "freq", parse_values("200:1500:25", "freq"), progress=True)
    charts.append(plot_sweep(freq, out_dir / "sweep.png",
                             f"preset {preset.name}: travel of one firing versus frequency"))
    episode = _demo_episode(out_dir / "episode.png", getattr(args, "env", None) or DEFAULT_ENV_ID,
                            getattr(args, "env_kwargs_dict", None) or {})
    charts.append(episode.pop("chart"))
    summary = {"preset": preset.name, "contact": table.report(), "calibration": preset.calibration,
               "reference_firing": firing.to_dict(), "window_hz": freq["window_hz"],
               "max_travel_m": freq.get("max_travel_m"), "episode": episode,
               "charts": [str(c) for c in charts]}
    (out_dir / "summary.json").write_text(json.dumps(summary, indent=2, default=json_default))
    summary["summary_json"] = str(out_dir / "summary.json")
    return summary


FIXED_FREQUENCY_HZ, FIXED_STROKE_M = 950.0, 200e-6   # the demo's fixed schedule's firing
PLANE_FREQUENCY_HZ, PLANE_STROKE_M = 600.0, 150e-6   # the plane's (950 Hz, 200 um detaches)
SCENE_FIRINGS = 4   # the positioner's and the plane's fixed schedule: this many firings


def _demo_episode(path, env_id=DEFAULT_ENV_ID, env_kwargs=None):
    """One episode of ``env_id`` (with ``env_kwargs``) with a fixed schedule, rendered: on the
    line every actuator fires 950 Hz, 200 um, no delay, towards 1 mm; on the positioner
    actuators 1 to 4 fire in turn so (towards 1 mm); on the plane :data:`SCENE_FIRINGS` firings
    (600 Hz, 150 um, no delay) of the actuator one pitch along +x of the part, towards two pitches along +x of the start."""
    import warnings

    import gymnasium as gym
    import numpy as np

    from ..env_ids import REGISTRY
    from ..envs.core import actions
    from ..plots import save_frames

    with warnings.catch_warnings():  # v0 when asked for: no "out of date" notice
        warnings.filterwarnings("ignore", message=".*is out of date", category=DeprecationWarning)
        env = gym.make(env_id, render_mode="rgb_array", **(env_kwargs or {}))
    u = env.unwrapped
    cfg = u.config
    geometry = REGISTRY[env_id].geometry if env_id in REGISTRY else "line"
    fh = actions.encode_actions(FIXED_FREQUENCY_HZ, FIXED_STROKE_M, 0.0, cfg)
    if geometry == "plane":
        fh = actions.encode_actions(PLANE_FREQUENCY_HZ, PLANE_STROKE_M, 0.0, cfg)
        (_, x1), _ = cfg.grid_box
        target = (min(x1, cfg.start[0] + 2 * cfg.spacing), cfg.start[1])
        aim = min(1.0, cfg.spacing / cfg.pick_reach) if cfg.pick_reach else 0.0

        def act(_k):
            return np.array([aim, 0.0, *fh], np.float32)
        what = f"{SCENE_FIRINGS} firings one pitch +x of the part, 600 Hz, 150 µm"
        where = f"target ({target[0] * 1e3:g}, {target[1] * 1e3:g}) mm"
    elif geometry == "positioner":
        target = 1e-3

        def act(k):
            aim = (u.positions[k] - u.x) / cfg.pick_reach if cfg.pick_reach else 0.0
            return np.array([np.clip(aim, -1.0, 1.0), fh[0], fh[1]], np.float32)
        what = f"actuators 1 to {SCENE_FIRINGS} fire in turn, 950 Hz, 200 µm"
        where = "target 1 mm"
    else:
        target = 1e-3

        def act(_k):
            return fh
        what = "every actuator fires 950 Hz, 200 µm, no delay"
        where = "target 1 mm"
    env.reset(seed=0, options={"target": target})
    frames, total, k = [env.render()], 0.0, 0
    while True:
        _, r, term, trunc, info = env.step(act(k))
        total += r
        k += 1
        frames.append(env.render())
        if term or trunc or (geometry != "line" and k >= SCENE_FIRINGS):
            break
    if geometry == "positioner" and info["outcome"] == "moving":
        info = {**info, "outcome": "rest"}   # every firing ends at rest; the schedule ended
    error = info.get("distance_m", info["position_error_m"])
    title = (f"{env_id}: a fixed schedule, not a policy ({what}); {where}, {info['outcome']}, "
             f"{'distance' if 'distance_m' in info else 'error'} {error * 1e6:.0f} µm")
    return {"chart": save_frames(frames, path, title=title), "env_id": env_id,
            "env_kwargs": env_kwargs or {}, "schedule": what, "target_m": target,
            "error_m": float(error), "return": total, **info}
