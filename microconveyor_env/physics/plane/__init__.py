"""The plane's physics: a grid of actuators under the surface, the part's motion in two
dimensions against the same Kogut–Etsion contact as the line (:mod:`.simulator` for the Python
interface, :mod:`.kernel` for the compiled integration, :mod:`.kinematics`, :mod:`.forces` and
:mod:`.events` for the surface, the contact forces and the stick/slip/detach events)."""
