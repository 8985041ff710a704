"""What every scene's envs share, written once: the config base and its field checks
(:mod:`.config`), the container of N parts that owns the state arrays, the bound compiled step and
the checked resets (:mod:`.parts`, thread choice :mod:`.threads`), a part's saved state
(:mod:`.part_state`), the single and the batched env built on it (:mod:`.single`,
:mod:`.vector`), the action decoding (:mod:`.actions`), the reward arithmetic (:mod:`.reward`),
the checks of what a user passes (:mod:`.checks`), the SB3 adapter (:mod:`.sb3`) and video
(:mod:`.video`, :mod:`.window`). A scene (the line, the plane) adds its geometry: its config, its
compiled step and task, its saved state's fields, its reset options and its info keys."""
