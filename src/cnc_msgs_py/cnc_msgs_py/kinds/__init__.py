"""The job kinds' parts of the ``cnc_job/1`` schema, one module per kind, and their registry.

A kind's module holds its block of a job document, its cross-field rules, the keys it has no
use for and what its spindle and tool must be (``cnc_msgs_py.kinds.kind.KindSchema``).
``cnc_msgs_py.job`` looks kinds up here and never switches on a kind's name: a new kind is a
new module, a line in KIND_SCHEMAS and its block's place in BLOCK_ORDER.
"""
from __future__ import annotations

from . import drill, move, path, program, sync, thread, turn
from .kind import KindSchema

# In the order a job's ``kind`` lists them (and a block of another kind is looked for).
KIND_SCHEMAS: dict[str, KindSchema] = {kind.name: kind for kind in (
    drill.KIND,
    turn.KIND,
    thread.KIND,
    move.KIND,
    sync.KIND,
    path.KIND,
    program.KIND,
)}
# Where the kinds' blocks stand among a job's keys: the order they are checked in and an
# unknown key's reason lists them.
BLOCK_ORDER = ("drill", "move", "sync", "turn", "thread", "path", "program")
