"""Model-predictive control of the conveyor: re-plan the remaining firings from the observed part
state after every firing.

* :mod:`.control`: the receding-horizon controller (:class:`MPC`, :class:`MPCSettings`,
  :class:`MPCEpisode`), its robust scoring and its seeding by a policy's plan;
* :mod:`.identification`: the episode's friction and mass factors fitted from observed firings;
* :mod:`.harness`: many episodes on worker processes (:func:`mpc_rollout`), worker deaths and
  reruns.
* :mod:`.positioner`: MicroPositioner-v0's one-step model-based controller (every reachable
  actuator, frequency and stroke tried on the model before each firing), with the nominal, an
  identified or the true model;
* :mod:`.seeded`: the conveyor's controller with a horizon of one firing, seeded by a policy
  (its firings, its last one re-aimed on the model), for many part states at once: DAgger's
  expert on MicroConveyor-v1.
"""
from .control import MPC, MPCEpisode, MPCSettings, observed
from .harness import MPCRollout, mpc_rollout

__all__ = ["MPC", "MPCEpisode", "MPCRollout", "MPCSettings", "mpc_rollout", "observed"]
