"""Model-predictive control of the conveyor: re-plan the remaining firings from the observed part
state after every firing (:mod:`.controller`)."""
