"""Refining a trained policy's aim on the simulator (``microconveyor refine``)."""
