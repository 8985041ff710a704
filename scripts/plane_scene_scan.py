"""Why MicroConveyor2D-v0's scene (docs/env.md, "MicroConveyor2D-v0"): from a part at rest at
typical points of a grid cell, fire random actions as the env would (an actuator nearest to an aim
point within one pitch of the part, 200 Hz to ``--fmax``, 100-200 um, no delay) and count how many
move the part by more than 25 um without detaching, on grids of several pitches and wavelengths
(chapter 4's surface, ``conveyor``).

    python3 scripts/plane_scene_scan.py [--samples 400] [--fmax 2000]

A part resting where no firing moves it can never be moved again: the scene must leave no such
point. One line per scene and point: detached fraction, moved fraction, median and largest move.
"""
from __future__ import annotations

import argparse

import numpy as np

from microconveyor_env.physics.plane import kernel as K
from microconveyor_env.physics.dynamics_kernel import DETACHED
from microconveyor_env.physics.plane.simulator import PlaneSimulator
from microconveyor_env.presets import load_preset

SCENES = ((0.6e-3, 0.35e-3), (0.6e-3, 0.5e-3), (1.0e-3, 0.25e-3), (1.5e-3, 0.5e-3),
          (2.0e-3, 0.5e-3))  # (wavelength, pitch) [m]


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--samples", type=int, default=400)
    p.add_argument("--fmax", type=float, default=2000.0)
    args = p.parse_args()
    rng = np.random.default_rng(0)
    rec, out = np.zeros((0, K.N_REC)), np.zeros(K.N_OUT)
    for wl, s in SCENES:
        sim = PlaneSimulator(load_preset("conveyor").contact, wavelength=wl, dt=1e-4,
                             min_steps=48, max_time=1.0)
        P, (tu, tq, tqu) = sim.params, sim.tables
        for where, (px, py) in (("cell centre", (s / 2, s / 2)), ("edge middle", (s / 2, 0.0)),
                                ("on an actuator", (0.0, 0.0))):
            moves, det = [], 0
            for _ in range(args.samples):
                ax, ay = px + rng.uniform(-s, s), py + rng.uniform(-s, s)
                cx, cy = np.floor(ax / s + 0.5) * s, np.floor(ay / s + 0.5) * s
                f = 200.0 * np.exp(rng.uniform() * np.log(args.fmax / 200.0))
                h = rng.uniform(100e-6, 200e-6)
                K.reset_out(out)
                x, y, _, _, _, o = K.fire(px, py, 0.0, 0.0, 0.0, cx, cy, f, h, 0.0, 1e-4, 48,
                                          True, 1.0, P, tu, tq, tqu, rec, out)
                if o == DETACHED:
                    det += 1
                else:
                    moves.append(np.hypot(x - px, y - py))
            m = np.array(moves)
            moved = m[m > 25e-6]
            print(f"WL {wl * 1e3:.1f} mm, pitch {s * 1e3:.2f} mm, {where:14s}: detached "
                  f"{det / args.samples:4.0%}, moved > 25 um {moved.size / args.samples:4.0%}"
                  + (f", median move {np.median(moved) * 1e6:4.0f} um, largest "
                     f"{moved.max() * 1e3:.2f} mm" if moved.size else ""))


if __name__ == "__main__":
    main()
