"""Open-loop planning: the black-box optimisers and the problems they solve (per-target plans on
the line and on the positioner, the dissertation's shared-parameter problem, Table 4.3)."""
