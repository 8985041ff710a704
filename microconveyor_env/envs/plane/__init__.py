"""The plane: a grid of actuators moves a part in two dimensions (MicroConveyor2D-v0, and -v1 under
per-episode randomisation). Its config
(:mod:`.config`), compiled step and task (:mod:`.step`, :mod:`.task`), part container
(:mod:`.state`), single and batched envs (:mod:`.env`, :mod:`.vector`) and rendering."""
