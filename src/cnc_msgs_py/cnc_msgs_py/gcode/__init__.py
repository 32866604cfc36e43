"""A G-code front end: RS274/NGC programs (LinuxCNC 2.9's dialect) into our job kinds.

ROS-free and planner-free, so that a cell controller can check a program before it sends it.
``lexer`` reads lines into words (values as ``expressions``), ``control`` runs O-word flow
over them with ``parameters`` (``system`` the read-only ones), ``modal`` holds the modal
groups and state, ``translate`` interprets line by line as they execute, ``drilling`` and
``lathe`` turn canned cycles into our methods (``cycles`` says how), ``arcs`` checks and
expands G2/G3, ``tools`` reads LinuxCNC tool tables. A bad program is refused at its
first bad line as ``line N: <word>: <reason>`` (``GcodeError``, a JobError).
docs/gcode.md lists the supported words and our own directive comments.
"""
from .lexer import GcodeError
from .translate import Context, Operation, machine_named, translate

__all__ = ["Context", "GcodeError", "Operation", "machine_named", "translate"]
