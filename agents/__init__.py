"""Agents for MicroConveyor-v0, built on top of :mod:`microconveyor_env` (which never imports
this package): the open-loop reach study (:mod:`.reach`), PPO training (:mod:`.train`) and
evaluation (:mod:`.evaluate`) with stable-baselines3, the shipped policy (:mod:`.policy`) and the
``microconveyor`` commands ``reach``, ``train``, ``evaluate`` and ``demo`` (:mod:`.cli`)."""
