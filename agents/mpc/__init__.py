"""Model-predictive control of the conveyor: re-plan the remaining firings from the observed part
state after every firing.

* :mod:`.control`: the receding-horizon controller (:class:`MPC`, :class:`MPCSettings`,
  :class:`MPCEpisode`), its robust scoring and its seeding by a policy's plan;
* :mod:`.identification`: the episode's friction and mass factors fitted from observed firings;
* :mod:`.harness`: many episodes on worker processes (:func:`mpc_rollout`), worker deaths and
  reruns.
"""
from .control import MPC, MPCEpisode, MPCSettings, observed
from .harness import MPCRollout, mpc_rollout

__all__ = ["MPC", "MPCEpisode", "MPCRollout", "MPCSettings", "mpc_rollout", "observed"]
