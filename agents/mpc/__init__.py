"""Model-predictive control on any scene planners serve (:mod:`agents.planning`): re-plan from
the observed part state after every firing.

* :mod:`.control`: the controller (:class:`MPC`, one loop for every scene), its planners (the
  line's receding horizon, :class:`MPCSettings`; the positioner's one-step search,
  :class:`OneStepSettings`) and its episode (:class:`MPCEpisode`);
* :mod:`.identification`: the episode's friction and mass factors fitted from observed firings;
* :mod:`.harness`: many episodes on worker processes (:func:`mpc_rollout`), worker deaths and
  reruns;
* :mod:`.experts`: the experts DAgger imitates, batched over many part states (the positioner's
  one-step search; the line's policy-seeded horizon of one firing).
"""
from .control import MPC, MPCEpisode, MPCSettings, OneStepSettings
from .harness import MPCRollout, mpc_rollout

__all__ = ["MPC", "MPCEpisode", "MPCRollout", "MPCSettings", "OneStepSettings", "mpc_rollout"]
