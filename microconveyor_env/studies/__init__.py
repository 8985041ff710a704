"""Studies built on the simulator: parameter sweeps, feasible windows, accuracy versus cost."""
