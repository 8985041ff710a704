"""What every scene's envs share, written once: the container of N parts that owns the state
arrays and the bound compiled step (:mod:`.parts`), and the batched env built on it
(:mod:`.vector`). A scene (the line, the plane) adds its geometry: its config, its compiled
step and task, its reset options and its info keys."""
