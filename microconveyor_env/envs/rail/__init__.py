"""What the two scenes on a line of actuators share (the line, MicroConveyor-v0/-v1, and the
positioner, MicroPositioner-v0), owned by neither: the 1-D config (:mod:`.config`), the
constants their compiled steps read (:mod:`.step`), the simulator, targets and starts of their
parts (:mod:`.parts`), the bounds of a saved state (:mod:`.part_state`) and the drawing of a
rail (:mod:`.render`)."""
