"""The line: actuators in a row carry a part along one axis (MicroConveyor-v0, -v1 and the goal
env). Its config and defaults (:mod:`.config`), its compiled step and task (:mod:`.step`,
:mod:`.task`), the part container (:mod:`.state`), the saved part state (:mod:`.part_state`), the
single, batched and goal envs (:mod:`.env`, :mod:`.vector`, :mod:`.goal`) and its rendering."""
