"""MicroPositioner-v0: a linear array of actuators along the whole target range, any actuator
free to fire, each firing run to rest (:mod:`.env`)."""
