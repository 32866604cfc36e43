"""Program jobs: a G-code program (``cnc_msgs_py.gcode``) run as one goal, its operations our
other kinds' jobs. The block::

    program:
      gcode: "G21 G90 ... M2"            # the program text
      tool_table: [{tool: 1, length: 50, diameter: 6}]   # T numbers; G43 applies the length
      work_offsets: {G55: {origin: [100, 0, 0]}}          # G55..G59 over the machine's var file; G54 is the job's setup
      stock: [[0, 20], [-40, 20]]         # G71's real stock, [z, radius] as turn.stock
      start: {x: 7, z: 4}                 # where the tool stands when the program begins
                                          # (else where the machine stands, if the program asks)
      start: {spindle_rpm: 1000}          # the spindle turning (M3) as the program begins, as an
                                          # operator's MDI S1000 M3 leaves it (else stopped)
      subroutines: [{name: peck, gcode: "o<peck> sub ... o<peck> endsub"}]   # <name>.ngc files
      optional_stop: true                 # M1 holds as M0 does (AXIS's default); false: M1 is skipped

Without ``tool_table`` the machine's own (``config/machines/<machine>.tbl``) holds the tools.
The program is translated and every operation validated as its kind's job when the document
is parsed, so a bad program is refused, by line and word, before anything moves.
"""
from __future__ import annotations

from types import SimpleNamespace

from ..schema import Bool, JobError, List, Num, Obj, Str
from .kind import MAX_LIST, KindSchema
from .turn import OUTLINE

MAX_PROGRAM_CHARS = 5_000_000
START_AXES = ("x", "y", "z")  # program.start's axes

TOOL = Obj({"tool": Num("1", min=1, max=99999, integer=True), "length": Num("mm", min=0.0, max=1000.0, default=0.0),
            "diameter": Num("mm", min=0.0, max=500.0, default=None), "nose_radius": Num("mm", min=0.0, max=10.0, default=0.0)})
SETUP = Obj({"origin": List(Num("mm"), length=3, default=[0.0, 0.0, 0.0]),
             "rotation_deg": List(Num("deg"), length=3, default=[0.0, 0.0, 0.0])})
PROGRAM = Obj({
    "gcode": Str(),
    "tool_table": List(TOOL, max_len=1000, default=None),
    "work_offsets": Obj({f"G{n}": Obj(SETUP.fields, default=None) for n in range(55, 60)}, default=None),
    "stock": List(OUTLINE.item, min_len=2, max_len=MAX_LIST, default=None),  # as turn.stock
    "start": Obj({**{k: Num("mm", default=None) for k in START_AXES},
                  "spindle_rpm": Num("rpm", gt=0.0, max=100_000.0, default=None)}, default=None),
    "subroutines": List(Obj({"name": Str(pattern=r"[A-Za-z0-9_.-]{1,64}"), "gcode": Str()}), max_len=1000, default=None),
    "optional_stop": Bool(default=True),
}, default=None)


def check(job: SimpleNamespace) -> None:
    """Everything is checked on the raw document (check_given): the translation needs mm."""
    if len(job.program.gcode) + sum(len(s.gcode) for s in job.program.subroutines or []) > MAX_PROGRAM_CHARS:
        raise JobError("program.gcode", f"longer than {MAX_PROGRAM_CHARS} characters (with its subroutines)")


def translate_program(doc: dict, job: SimpleNamespace) -> None:
    """The program's operations in ``job.program.operations``: a list of (line, job in SI,
    its document in mm), its hold points (M0/M1) in ``.holds``; any error is
    ``line N: <word>: <reason>``.

    Without ``start``, a program that reads where the tool stands before it says so (a G91
    move, G92, a cycle from the tool's place) starts where the machine stands, as LinuxCNC's
    does: it is checked here from the program's origin and ``job.program.start_from_machine``
    says that the planner translates it again from the machine's position (``operations_from``).
    """
    from ..gcode import Context, GcodeError
    from ..gcode.tools import machine_tool_table
    from ..gcode.var_file import machine_work_offsets
    block = doc["program"]
    table = {}
    tools = block.get("tool_table")
    for entry in (machine_tool_table(job.machine) or []) if tools is None else tools:
        if entry["tool"] in table:
            raise JobError("program.tool_table", f"tool {entry['tool']} given twice")
        table[entry["tool"]] = {k: v for k, v in entry.items() if k != "tool"}
    given = block.get("start") or {}
    start = {k: given[k] for k in START_AXES if given.get(k) is not None}
    ctx = Context(job_id=job.job_id, machine=job.machine, setup=doc.get("setup") or {}, tool_table=table,
                  work_offsets={**machine_work_offsets(job.machine),
                                **{k: v for k, v in (block.get("work_offsets") or {}).items() if v is not None}},
                  stock=block.get("stock"), start=start, spindle_rpm=given.get("spindle_rpm"),
                  subroutines={s["name"].lower(): s["gcode"] for s in block.get("subroutines") or []},
                  optional_stop=block.get("optional_stop", True))
    job.program.context, job.program.start_from_machine = ctx, False
    try:
        job.program.operations = _operations(block["gcode"], ctx)
    except GcodeError as err:
        if not err.needs_start or start:
            raise
        from ..gcode.modal import machine_axes
        job.program.start_from_machine = True
        job.program.operations = operations_from(job, {a: 0.0 for a in START_AXES if a in machine_axes(job.machine)})


def operations_from(job: SimpleNamespace, start_mm: dict[str, float]) -> list:
    """A ``start_from_machine`` program's operations from ``start_mm`` (program coordinates,
    mm: where the machine stands when it begins), with its hold points (``.holds``)."""
    from dataclasses import replace
    return _operations(job.program.gcode, replace(job.program.context, start=dict(start_mm)))


def _operations(gcode: str, ctx) -> list:
    from ..gcode import GcodeError, translate
    from ..gcode.translate import Operations
    from ..job import parse_job  # the job schema holds this module: imported when used
    translated = translate(gcode, ctx)
    operations = Operations(holds=translated.holds)  # M0/M1: the planner holds there (cnc_planner.holding)
    for op in translated:
        try:
            operations.append((op.line, parse_job(op.doc), op.doc))
        except GcodeError:
            raise
        except JobError as err:
            raise GcodeError(op.line, op.doc["kind"], str(err)) from err
    return operations


KIND = KindSchema(
    "program", PROGRAM, check, check_given=translate_program,
    unused={"tool": "the program's tool table and T words give the tool",
            "spindle_rpm": "the program's S and M3 words give the speed",
            "surface_speed": "the program's G96 D S words give it",
            "vibration": "the program's (CNC,VIBRATION ...) comments give it",
            "setup.work_offset": "G54..G59 select the program's work offsets"},
)
