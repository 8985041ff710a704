"""Agents for MicroConveyor-v0, built on top of :mod:`microconveyor_env` (which never imports
this package): open-loop optimisation (:mod:`.search` DE and CMA-ES, :mod:`.open_loop` one plan
per target, :mod:`.dissertation` the dissertation's shared-parameter problem, :mod:`.table43`),
the open-loop reach study (:mod:`.reach`), PPO training (:mod:`.train`) and evaluation
(:mod:`.evaluate`) with stable-baselines3, the shipped policy (:mod:`.policy`) and the
``microconveyor`` commands ``reach``, ``optimize``, ``train``, ``evaluate`` and ``demo``
(:mod:`.cli`, :mod:`.cli_optimize`)."""
