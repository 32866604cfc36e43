"""Job documents (cnc_job/1): parsing, unit conversion to SI, field-naming errors.

The example documents are DESIGN.md's job example split by kind; expected SI values
are worked out by hand (1 mm = 1e-3 m, 1 min = 60 s, 1 rev = 2*pi rad).
"""
from __future__ import annotations

import copy
import dataclasses
import json
import math

import pytest

from cnc_msgs_py import units
from cnc_msgs_py.job import JOB, KINDS, MAX_LIST, SCHEMA, decode_job, job_id_of, load_job_file, parse_job
from cnc_msgs_py.kinds import BLOCK_ORDER, KIND_SCHEMAS
from cnc_msgs_py.schema import JobError
from cnc_msgs_py.status import FINAL_STATES, STATES, Status, decode_cancel, encode_cancel

# --- DESIGN.md's example, one document per kind ---------------------------------------

DRILL_DOC = {
    "schema": "cnc_job/1",
    "job_id": "drill-001",
    "kind": "drill",
    "machine": "mill3",
    "tool": {"length": 0.0, "diameter": 6.0},
    "setup": {"origin": [0, 0, 0], "rotation_deg": [0, 0, 0]},
    "spindle_rpm": 3000,
    "drill": {
        "holes": [[0, 0], [10, 0], [20, 0]],
        "surface_z": 0.0,
        "depth": 5.0,
        "r_gap": 2.0,
        "feed": 1200,
        "overlap": "auto",
        "mode": "auto",
        "gentle_air_accel": False,
    },
}

MOVE_DOC = {
    "schema": "cnc_job/1",
    "job_id": "move-001",
    "kind": "move",
    "machine": "mill3",
    "move": [
        {"rapid": {"x": 10, "z": 5}},
        {"linear": {"z": -20}, "feed": 60},
        {"dwell": 0.5},
    ],
}

TURN_DOC = {
    "schema": "cnc_job/1",
    "job_id": "turn-001",
    "kind": "turn",
    "machine": "lathe",
    "spindle_rpm": 1500,
    "turn": {
        "stock": [[0, 20], [-40, 20]],
        "profile": [[0, 8], [-10, 8], [-10, 14], [-40, 14]],
        "depth_of_cut": 1.5,
        "clearance": 0.5,
        "feed": 0.15,
        "origin": [5, 25],
        "finish_allowance": 0.2,
    },
    "vibration": {"D": 1.5, "Q": 1.2},
}

THREAD_DOC = {
    "schema": "cnc_job/1",
    "job_id": "thread-001",
    "kind": "thread",
    "machine": "lathe",
    "spindle_rpm": 600,
    "thread": {
        "start_z": 4.0,
        "end_z": -16.0,
        "major_radius": 6.0,
        "pitch": 1.75,
        "depth": 1.07,
        "passes": 6,
        "infeed_angle": 29.5,
        "spring_passes": 1,
    },
    "vibration": {"D": 1.5, "Q": 1.2, "phase_shift": 180, "D_step": 0.5},
}

PATH_DOC = {
    "schema": "cnc_job/1",
    "job_id": "path-001",
    "kind": "path",
    "machine": "mill3",
    "path": {"points": [[0, 0, 5], [10, 0, 0], [10, 10, 0]], "feed": 600},
}

PROGRAM_DOC = {
    "schema": "cnc_job/1",
    "job_id": "program-001",
    "kind": "program",
    "machine": "mill3",
    "program": {"gcode": "G21 G90 G17\nM3 S3000\nG0 X0 Y0 Z5\nG99 G81 X0 Y0 Z-5 R2 F1200\nX10\nX20\nG80\nM2\n"},
}

SYNC_DOC = {
    "schema": "cnc_job/1",
    "job_id": "sync-001",
    "kind": "sync",
    "machine": "lathe",
    "spindle_rpm": 600,
    "sync": [{"rapid": {"x": 12, "z": 5}}, {"sync": {"z": -20}, "lead": 2.0}, {"rapid": {"x": 14}}],
}

DOCS = {"drill": DRILL_DOC, "move": MOVE_DOC, "turn": TURN_DOC, "thread": THREAD_DOC, "path": PATH_DOC,
        "program": PROGRAM_DOC, "sync": SYNC_DOC}


def doc(kind: str) -> dict:
    """A fresh, mutable copy of the example of ``kind``."""
    return copy.deepcopy(DOCS[kind])


def rejected(document, field: str, *words: str) -> JobError:
    """Parse ``document``, expect a JobError at ``field`` whose reason holds ``words``."""
    with pytest.raises(JobError) as info:
        parse_job(document)
    err = info.value
    assert err.field == field, str(err)
    for word in words:
        assert word in err.reason, str(err)
    assert str(err).startswith(f"{field}: ") if field else True
    return err


# --- every kind parses ------------------------------------------------------------------

def test_the_examples_cover_every_kind():
    assert sorted(DOCS) == sorted(KINDS)


def test_the_job_schema_is_built_from_the_kind_registry():
    assert sorted(BLOCK_ORDER) == sorted(KIND_SCHEMAS) == sorted(KINDS)
    for name, kind in KIND_SCHEMAS.items():
        assert kind.name == name
        assert JOB.fields[name] is kind.block


def test_a_kinds_rules_are_the_ones_its_registry_entry_holds(monkeypatch):
    def refuse(job):
        raise JobError("path.points", "refused by the registered rule")

    monkeypatch.setitem(KIND_SCHEMAS, "path", dataclasses.replace(KIND_SCHEMAS["path"], check=refuse))
    rejected(doc("path"), "path.points", "refused by the registered rule")
    monkeypatch.setitem(KIND_SCHEMAS, "move", dataclasses.replace(KIND_SCHEMAS["move"], needs_spindle=True))
    rejected(doc("move"), "spindle_rpm", "must be > 0 for a move job")


@pytest.mark.parametrize("kind", KINDS)
def test_every_kind_of_the_design_example_parses(kind):
    job = parse_job(doc(kind))
    assert job.kind == kind
    assert job.schema == SCHEMA
    assert getattr(job, kind) is not None
    for other in KINDS:
        if other != kind:
            assert getattr(job, other) is None


@pytest.mark.parametrize("kind", KINDS)
def test_every_kind_parses_from_json_text_too(kind):
    assert parse_job(decode_job(json.dumps(doc(kind)))).job_id == DOCS[kind]["job_id"]


def test_drill_example_in_si_units():
    job = parse_job(doc("drill"))
    d = job.drill
    assert d.holes == [[0.0, 0.0], [0.010, 0.0], [0.020, 0.0]]
    assert d.depth == pytest.approx(0.005, abs=1e-15)
    assert d.r_gap == pytest.approx(0.002, abs=1e-15)
    assert d.feed == pytest.approx(0.02, abs=1e-15)  # 1200 mm/min = 20 mm/s
    assert (d.overlap, d.mode, d.gentle_air_accel) == ("auto", "auto", False)
    assert job.spindle_rpm == pytest.approx(314.159265358979, abs=1e-9)  # 3000 * 2 pi / 60 = 100 pi
    assert job.tool.diameter == pytest.approx(0.006, abs=1e-15)
    assert job.tool.length == 0.0 and job.tool.nose_radius == 0.0
    assert job.setup.origin == [0.0, 0.0, 0.0] and job.setup.rotation_deg == [0.0, 0.0, 0.0]


def test_move_example_in_si_units_and_defaults():
    job = parse_job(doc("move"))
    rapid, linear, dwell = job.move
    assert (rapid.rapid.x, rapid.rapid.z) == (pytest.approx(0.010), pytest.approx(0.005))
    assert rapid.rapid.y is None and rapid.linear is None and rapid.feed is None and rapid.dwell is None
    assert linear.linear.z == pytest.approx(-0.020)
    assert linear.feed == pytest.approx(0.001, abs=1e-15)  # 60 mm/min = 1 mm/s
    assert dwell.dwell == 0.5  # seconds, no conversion
    # Optional blocks default: no spindle, zero setup, tool of length 0.
    assert job.spindle_rpm == 0.0
    assert job.setup.origin == [0.0, 0.0, 0.0]
    assert job.tool.length == 0.0 and job.tool.diameter is None


def test_turn_example_in_si_units():
    job = parse_job(doc("turn"))
    t = job.turn
    assert t.stock == [[0.0, 0.020], [-0.040, 0.020]]
    assert t.profile[2] == [pytest.approx(-0.010), pytest.approx(0.014)]
    assert t.depth_of_cut == pytest.approx(0.0015, abs=1e-15)
    assert t.clearance == pytest.approx(0.0005, abs=1e-15)
    assert t.feed == pytest.approx(0.00015, abs=1e-15)  # 0.15 mm/rev -> 0.00015 m/rev
    assert t.origin == [pytest.approx(0.005), pytest.approx(0.025)]
    assert t.finish_allowance == pytest.approx(0.0002, abs=1e-15)
    assert t.finishing_pass is False
    assert (job.vibration.D, job.vibration.Q, job.vibration.E, job.vibration.R) == (1.5, 1.2, None, None)
    assert job.spindle_rpm == pytest.approx(50 * math.pi)  # 1500 rpm = 25 rev/s


def test_thread_example_in_si_units():
    job = parse_job(doc("thread"))
    t = job.thread
    assert (t.start_z, t.end_z) == (pytest.approx(0.004), pytest.approx(-0.016))
    assert t.major_radius == pytest.approx(0.006)
    assert t.pitch == pytest.approx(0.00175, abs=1e-15)
    assert t.depth == pytest.approx(0.00107, abs=1e-15)
    assert (t.passes, t.spring_passes, t.starts, t.internal, t.depths) == (6, 1, 1, False, None)
    assert isinstance(t.passes, int)
    assert t.infeed_angle == pytest.approx(0.514872129338327, abs=1e-12)  # 29.5 * pi / 180
    assert job.vibration.phase_shift == pytest.approx(math.pi)  # 180 deg
    assert job.vibration.D_step == 0.5
    assert job.spindle_rpm == pytest.approx(20 * math.pi)  # 600 rpm = 10 rev/s


def test_path_example_in_si_units_and_defaults():
    job = parse_job(doc("path"))
    p = job.path
    assert p.points[0] == [0.0, 0.0, pytest.approx(0.005)]
    assert p.feed == pytest.approx(0.01, abs=1e-15)  # 600 mm/min = 10 mm/s
    assert p.chord_tolerance == pytest.approx(1e-5, abs=1e-18)  # default 0.01 mm
    assert p.tool_axis is None


def test_thread_with_explicit_depths_and_e_r_vibration_parses():
    d = doc("thread")
    d["thread"]["depths"] = [0.5, 0.8, 1.0, 1.07]
    d["vibration"] = {"E": 2.0, "R": 0.5, "Q": 1.0}
    job = parse_job(d)
    assert job.thread.depths == [pytest.approx(0.0005), pytest.approx(0.0008), pytest.approx(0.001),
                                 pytest.approx(0.00107)]
    assert (job.vibration.D, job.vibration.E, job.vibration.R) == (None, 2.0, 0.5)


@pytest.mark.parametrize("mode", ["auto", 1, 2, 3, 2.0])
def test_drill_modes(mode):
    d = doc("drill")
    d["drill"]["mode"] = mode
    assert parse_job(d).drill.mode == (mode if mode == "auto" else int(mode))


def test_null_optional_value_takes_the_default():
    d = doc("drill")
    d["drill"]["r_gap"] = None
    assert parse_job(d).drill.r_gap == pytest.approx(0.002)


# --- units ------------------------------------------------------------------------------

def test_unit_conversions_hand_checked():
    assert units.mm_per_min(1200) == pytest.approx(0.02, abs=1e-15)
    assert units.mm_per_min(60) == pytest.approx(0.001, abs=1e-15)
    assert units.rpm(3000) == pytest.approx(314.159265358979, abs=1e-9)
    assert units.rpm(60) == pytest.approx(2 * math.pi)  # 1 rev/s
    assert units.deg(29.5) == pytest.approx(0.514872129338327, abs=1e-12)
    assert units.deg(180) == pytest.approx(math.pi)
    assert units.mm(0.15) == pytest.approx(0.00015, abs=1e-18)
    assert units.CONVERTERS["mm/rev"](0.15) == pytest.approx(0.00015, abs=1e-18)
    assert units.CONVERTERS["1"](3) == 3.0


def test_unit_conversions_invert():
    assert units.to_mm(units.mm(12.5)) == pytest.approx(12.5)
    assert units.to_mm_per_min(0.02) == pytest.approx(1200.0)
    assert units.to_rpm(100 * math.pi) == pytest.approx(3000.0)
    assert units.to_deg(math.pi / 2) == pytest.approx(90.0)


# --- errors name the field and the reason -------------------------------------------------

@pytest.mark.parametrize("where, field", [
    ((), "colour"),
    (("drill",), "drill.colour"),
    (("tool",), "tool.colour"),
    (("setup",), "setup.colour"),
])
def test_unknown_key_at_any_depth(where, field):
    d = doc("drill")
    target = d
    for key in where:
        target = target[key]
    target["colour"] = "red"
    rejected(d, field, "unknown key")


def test_unknown_key_inside_a_move_target():
    d = doc("move")
    d["move"][0]["rapid"]["w"] = 1.0
    rejected(d, "move[0].rapid.w", "unknown key")


def test_unknown_key_inside_a_move_entry():
    d = doc("move")
    d["move"][1]["speed"] = 5
    rejected(d, "move[1].speed", "unknown key")


def test_unknown_key_in_vibration():
    d = doc("turn")
    d["vibration"]["amplitude"] = 0.1
    rejected(d, "vibration.amplitude", "unknown key")


@pytest.mark.parametrize("key", ["schema", "job_id", "kind", "machine"])
def test_missing_required_top_level(key):
    d = doc("drill")
    del d[key]
    rejected(d, key, "required")


@pytest.mark.parametrize("key", ["holes", "depth", "feed"])
def test_missing_required_nested(key):
    d = doc("drill")
    del d["drill"][key]
    rejected(d, f"drill.{key}", "required")


def test_missing_block_of_the_kind():
    d = doc("drill")
    del d["drill"]
    rejected(d, "drill", "required")


def test_block_of_another_kind_is_refused():
    d = doc("drill")
    d["path"] = copy.deepcopy(PATH_DOC["path"])
    rejected(d, "path", "not allowed")


def test_spindle_needed_for_drilling():
    d = doc("drill")
    del d["spindle_rpm"]
    rejected(d, "spindle_rpm", "> 0")


@pytest.mark.parametrize("path, value, field, words", [
    (("drill", "holes"), "0,0", "drill.holes", ("expected a list",)),
    (("drill", "holes", 1), [10, 0, 0], "drill.holes[1]", ("expected 2 values",)),
    (("drill", "holes", 2, 0), "20", "drill.holes[2][0]", ("expected a number",)),
    (("drill", "depth"), "5", "drill.depth", ("expected a number", "mm")),
    (("drill", "overlap"), True, "drill.overlap", ("expected a string",)),
    (("drill", "gentle_air_accel"), "no", "drill.gentle_air_accel", ("true or false",)),
    (("drill",), [1, 2], "drill", ("expected a mapping",)),
    (("job_id",), 17, "job_id", ("expected a string",)),
    (("spindle_rpm",), "3000", "spindle_rpm", ("expected a number",)),
])
def test_wrong_type_names_the_field(path, value, field, words):
    d = doc("drill")
    target = d
    for key in path[:-1]:
        target = target[key]
    target[path[-1]] = value
    rejected(d, field, *words)


@pytest.mark.parametrize("value", [float("nan"), float("inf"), float("-inf")])
def test_non_finite_numbers_are_refused(value):
    d = doc("drill")
    d["drill"]["feed"] = value
    rejected(d, "drill.feed", "finite")


def test_nan_in_json_text_is_refused_at_its_field():
    text = json.dumps(doc("move")).replace('"z": -20', '"z": NaN')
    assert "NaN" in text
    rejected(decode_job(text), "move[1].linear.z", "finite")


def test_infinity_in_a_hole_is_refused():
    d = doc("drill")
    d["drill"]["holes"][1][1] = float("inf")
    rejected(d, "drill.holes[1][1]", "finite")


def test_negative_depth():
    d = doc("drill")
    d["drill"]["depth"] = -5.0
    err = rejected(d, "drill.depth", "must be > 0", "-5")
    assert "mm" in err.reason


def test_zero_feed():
    d = doc("drill")
    d["drill"]["feed"] = 0
    rejected(d, "drill.feed", "must be > 0")


def test_value_above_maximum():
    d = doc("drill")
    d["drill"]["r_gap"] = 51.0
    rejected(d, "drill.r_gap", "must be <= 50")


@pytest.mark.parametrize("mode", [0, 4, 2.5, "2", "fast", True])
def test_bad_drill_mode(mode):
    d = doc("drill")
    d["drill"]["mode"] = mode
    rejected(d, "drill.mode", "auto, 1, 2 or 3")


def test_bad_overlap_choice_lists_the_choices():
    d = doc("drill")
    d["drill"]["overlap"] = "on"
    rejected(d, "drill.overlap", "auto", "off", "'on'")


@pytest.mark.parametrize("schema", ["cnc_job/2", "cnc_job", ""])
def test_wrong_schema(schema):
    d = doc("drill")
    d["schema"] = schema
    rejected(d, "schema", SCHEMA)


def test_unknown_kind():
    d = doc("drill")
    d["kind"] = "mill"
    rejected(d, "kind", "expected one of")


@pytest.mark.parametrize("job_id", ["has space", "", "x" * 65, "semi;colon"])
def test_bad_job_id(job_id):
    d = doc("drill")
    d["job_id"] = job_id
    rejected(d, "job_id", "does not match")


@pytest.mark.parametrize("path, field", [
    (("spindle_rpm",), "spindle_rpm"),
    (("drill", "depth"), "drill.depth"),
    (("drill", "holes", 0, 0), "drill.holes[0][0]"),
    (("tool", "length"), "tool.length"),
])
def test_bool_given_as_number(path, field):
    d = doc("drill")
    target = d
    for key in path[:-1]:
        target = target[key]
    target[path[-1]] = True
    rejected(d, field, "expected a number", "True")


def test_integer_field_refuses_fraction_and_bool():
    d = doc("thread")
    d["thread"]["passes"] = 2.5
    rejected(d, "thread.passes", "whole number")
    d["thread"]["passes"] = True
    rejected(d, "thread.passes", "expected a number")


def test_list_longer_than_max_list():
    d = doc("drill")
    d["drill"]["holes"] = [[0, 0]] * (MAX_LIST + 1)
    rejected(d, "drill.holes", f"{MAX_LIST + 1} entries", f"maximum {MAX_LIST}")


def test_move_list_longer_than_max_list():
    d = doc("move")
    d["move"] = [{"dwell": 1.0}] * (MAX_LIST + 1)
    rejected(d, "move", "more than the maximum")


def test_list_of_exactly_max_list_is_accepted():
    d = doc("drill")
    d["drill"]["holes"] = [[0, 0]] * MAX_LIST
    assert len(parse_job(d).drill.holes) == MAX_LIST


def test_empty_list_is_refused():
    d = doc("drill")
    d["drill"]["holes"] = []
    rejected(d, "drill.holes", "at least 1")


@pytest.mark.parametrize("entry", [
    {"rapid": {"x": 1}, "linear": {"x": 2}, "feed": 60},
    {"rapid": {"x": 1}, "dwell": 1.0},
    {"linear": {"x": 1}, "dwell": 1.0, "feed": 60},
    {},
])
def test_move_entry_needs_exactly_one_of_rapid_linear_dwell(entry):
    d = doc("move")
    d["move"].insert(1, entry)
    rejected(d, "move[1]", "exactly one of rapid, linear, dwell")


def test_linear_without_feed():
    d = doc("move")
    del d["move"][1]["feed"]
    rejected(d, "move[1].feed", "required for a linear move")


def test_rapid_with_feed():
    d = doc("move")
    d["move"][0]["feed"] = 100
    rejected(d, "move[0].feed", "only a linear move")


def test_move_naming_no_axis():
    d = doc("move")
    d["move"][0] = {"rapid": {}}
    rejected(d, "move[0].rapid", "names no axis")


def test_negative_dwell():
    d = doc("move")
    d["move"][2]["dwell"] = -1
    rejected(d, "move[2].dwell", "must be > 0")


def test_vibration_with_d_and_e_both():
    d = doc("turn")
    d["vibration"] = {"D": 1.5, "E": 2.0, "Q": 1.2}
    rejected(d, "vibration", "either D or E and R, not both")


def test_vibration_with_neither_d_nor_e_r():
    d = doc("turn")
    d["vibration"] = {"Q": 1.2, "E": 2.0}
    rejected(d, "vibration", "give D, or E and R")


def test_vibration_retreat_longer_than_e():
    d = doc("turn")
    d["vibration"] = {"Q": 1.2, "E": 2.0, "R": 2.0}
    rejected(d, "vibration.R", "fewer than E")


def test_vibration_on_a_move_needs_the_spindle():
    d = doc("move")
    d["vibration"] = {"D": 1.5, "Q": 1.2}
    rejected(d, "spindle_rpm", "vibration")


def test_vibration_d_needs_q():
    d = doc("turn")
    d["vibration"] = {"D": 1.5}
    rejected(d, "vibration.Q", "required with D")


def test_vibration_e_r_without_q_parses_and_needs_r_below_half_e():
    d = doc("drill")
    d["vibration"] = {"E": 2, "R": 0.5}
    assert parse_job(d).vibration.Q is None
    d["vibration"] = {"E": 2, "R": 1}
    rejected(d, "vibration.R", "equal speed", "R < E/2 = 1", "give Q")
    d["vibration"] = {"E": 2, "R": 1, "Q": 1.2}  # with Q the retreat may take half the vibration
    assert parse_job(d).vibration.Q == 1.2


@pytest.mark.parametrize("kind, key, value", [
    ("drill", "vibration.phase_shift", 180), ("drill", "vibration.D_step", 0.5),
    ("move", "vibration.phase_shift", 90), ("turn", "vibration.D_step", 0.1),
    ("drill", "tool.nose_radius", 0.4),
])
def test_a_key_the_kind_does_not_use_is_refused_by_name(kind, key, value):
    d = doc(kind)
    if kind == "move":
        d["spindle_rpm"] = 1000
    if key.startswith("vibration"):
        d["vibration"] = {"D": 1.5, "Q": 1.2}
    block, name = key.split(".")
    d.setdefault(block, {})[name] = value
    rejected(d, key, f"not used by a {kind} job")


@pytest.mark.parametrize("key, value", [("mode", 2), ("gentle_air_accel", True)])
def test_overlap_only_keys_are_refused_on_the_conventional_cycle(key, value):
    d = doc("drill")
    d["drill"]["mode"] = None
    d["drill"]["gentle_air_accel"] = None
    d["drill"]["overlap"] = "off"
    assert parse_job(d).drill.overlap == "off"
    d["drill"][key] = value
    rejected(d, f"drill.{key}", "not used", "overlap: off")


def test_thread_keeps_its_vibration_keys():
    d = doc("thread")
    d["vibration"] = {"D": 1.5, "Q": 1.2, "phase_shift": 180, "D_step": 0.5}
    assert parse_job(d).vibration.D_step == 0.5


def test_a_lathe_tool_of_diameter_zero_is_accepted():
    d = doc("turn")
    d["tool"] = {"diameter": 0, "nose_radius": 0.4}
    assert parse_job(d).tool.diameter == 0.0
    d["tool"]["diameter"] = -1
    rejected(d, "tool.diameter", ">= 0")


def test_drill_dwell_in_seconds():
    d = doc("drill")
    assert parse_job(d).drill.dwell == 0.0
    d["drill"]["dwell"] = 0.5
    assert parse_job(d).drill.dwell == 0.5
    d["drill"]["dwell"] = -0.1
    rejected(d, "drill.dwell", ">= 0")


@pytest.mark.parametrize("end_z", [4.0, 10.0])
def test_thread_end_z_not_left_of_start_z(end_z):
    d = doc("thread")
    d["thread"]["end_z"] = end_z
    rejected(d, "thread.end_z", "start_z")


def test_thread_deeper_than_its_radius():
    d = doc("thread")
    d["thread"]["depth"] = 6.0
    rejected(d, "thread.depth", "major_radius")


def test_thread_depths_must_increase_and_end_at_depth():
    d = doc("thread")
    d["thread"]["depths"] = [0.5, 0.5, 1.07]
    rejected(d, "thread.depths", "increase")
    d["thread"]["depths"] = [0.5, 1.0]
    rejected(d, "thread.depths", "thread.depth")


def test_infeed_angle_beyond_90_degrees():
    d = doc("thread")
    d["thread"]["infeed_angle"] = 91
    rejected(d, "thread.infeed_angle", "<= 90")


def test_path_tool_axis_needs_one_vector_per_point():
    d = doc("path")
    d["path"]["tool_axis"] = [[0, 0, 1], [0, 0, 1]]
    rejected(d, "path.tool_axis", "one vector per point")


def test_a_document_that_is_not_a_mapping():
    with pytest.raises(JobError) as info:
        parse_job([DRILL_DOC])
    assert info.value.field == "" and "expected a mapping" in info.value.reason


# --- decoding and files -------------------------------------------------------------------

@pytest.mark.parametrize("text", ['{"schema": "cnc_job/1",', "", "not json", "{'single': 1}"])
def test_decode_job_on_malformed_json(text):
    with pytest.raises(JobError) as info:
        decode_job(text)
    assert info.value.field == ""
    assert "not valid JSON" in info.value.reason
    assert "line 1" in info.value.reason


def test_decode_job_reports_line_and_column():
    with pytest.raises(JobError) as info:
        decode_job('{\n  "a": 1,\n  "b": }')
    assert "line 3 column 8" in info.value.reason


def test_decoded_non_mapping_is_then_refused_by_parse():
    with pytest.raises(JobError, match="expected a mapping"):
        parse_job(decode_job("[1, 2, 3]"))


def test_load_job_file_yaml_and_json(tmp_path):
    (tmp_path / "job.yaml").write_text(
        "schema: cnc_job/1\njob_id: y-1\nkind: move\nmachine: mill3\n"
        "move:\n  - {rapid: {x: 10, z: 5}}\n  - {linear: {z: -20}, feed: 60}\n"
    )
    (tmp_path / "job.json").write_text(json.dumps(doc("drill")))
    job = parse_job(load_job_file(tmp_path / "job.yaml"))
    assert job.job_id == "y-1" and job.move[1].feed == pytest.approx(0.001)
    assert parse_job(load_job_file(str(tmp_path / "job.json"))).drill.feed == pytest.approx(0.02)


def test_load_job_file_missing(tmp_path):
    path = tmp_path / "nope.yaml"
    with pytest.raises(JobError) as info:
        load_job_file(path)
    assert "cannot read job file" in info.value.reason and str(path) in info.value.reason


@pytest.mark.parametrize("text", ["- 1\n- 2\n", "just a string\n", "", "42\n"])
def test_load_job_file_not_a_mapping(tmp_path, text):
    path = tmp_path / "job.yaml"
    path.write_text(text)
    with pytest.raises(JobError, match="must hold a mapping"):
        load_job_file(path)


def test_load_job_file_invalid_yaml(tmp_path):
    path = tmp_path / "job.yaml"
    path.write_text("a: [1, 2\n")
    with pytest.raises(JobError, match="not valid YAML"):
        load_job_file(path)


def test_job_id_of_invalid_documents():
    assert job_id_of({"job_id": "abc", "kind": 3}) == "abc"
    assert job_id_of({"job_id": 7}) == ""
    assert job_id_of([1]) == ""
    assert job_id_of(None) == ""
    assert job_id_of({"job_id": "z" * 100}) == "z" * 64


def test_shipped_example_jobs_parse():
    from pathlib import Path

    jobs = sorted((Path(__file__).resolve().parents[3] / "config" / "jobs").glob("*.yaml"))
    assert jobs, "config/jobs holds example jobs"
    for path in jobs:
        assert parse_job(load_job_file(path)).schema == SCHEMA, path


# --- status and cancel ------------------------------------------------------------------

def test_status_round_trip():
    status = Status("drill-001", "succeeded", reason="", progress=1.0, phase="hole 3 S3",
                    elapsed_s=12.5, duration_s=12.25, cycle_time_s=12.5, detail={"S1": 3})
    text = status.encode()
    assert json.loads(text)["schema"] == "cnc_status/1"
    back = Status.decode(text)
    assert back == status
    assert back.final


def test_status_round_trip_defaults_and_running_is_not_final():
    status = Status("j", "running", progress=0.25)
    back = Status.decode(status.encode())
    assert back == status and back.cycle_time_s is None and back.detail == {}
    assert not back.final


def test_final_states():
    assert set(FINAL_STATES) == {"rejected", "succeeded", "aborted", "canceled"}
    assert [Status("j", s).final for s in STATES] == [s in FINAL_STATES for s in STATES]


@pytest.mark.parametrize("text", [
    json.dumps({"job_id": "j", "state": "running", "schema": "other/1"}),
    json.dumps({"job_id": "j", "state": "flying", "schema": "cnc_status/1"}),
    json.dumps({"job_id": "j", "state": "running"}),
])
def test_status_decode_refuses_other_documents(text):
    with pytest.raises(ValueError, match="not a cnc_status/1 document"):
        Status.decode(text)


def test_cancel_codec():
    assert encode_cancel("drill-001") == "drill-001"
    assert decode_cancel("  drill-001\n") == "drill-001"


# --- turning: axial allowance and arcs in the outlines ------------------------------------

def test_turn_axial_allowance_defaults_to_a_tenth():
    assert parse_job(doc("turn")).turn.finish_allowance_z == pytest.approx(0.0001, abs=1e-15)
    d = doc("turn")
    d["turn"]["finish_allowance_z"] = 0.05
    assert parse_job(d).turn.finish_allowance_z == pytest.approx(0.00005, abs=1e-15)
    d["turn"]["finish_allowance_z"] = -0.1
    rejected(d, "turn.finish_allowance_z", "must be >= 0")


def _arc_doc(entry) -> dict:
    d = doc("turn")
    d["turn"]["profile"] = [[0, 8], entry, [-15, 12], [-40, 12]]
    return d


@pytest.mark.parametrize("entry", [
    {"arc_to": [-4, 12], "radius": 4},
    {"arc_to": [-4, 12], "center": [-4, 8]},
    {"arc_to": [-4, 12], "center": [-4, 8], "radius": 4},
])
def test_turn_arc_by_radius_or_center_expands_into_chords(entry):
    profile = parse_job(_arc_doc(entry)).turn.profile
    arc = profile[: len(profile) - 2]
    assert arc[0] == [0.0, 0.008] and arc[-1] == [pytest.approx(-0.004), pytest.approx(0.012)]
    assert len(arc) > 10  # chords within 1 um of a 4 mm arc
    for z, x in arc:
        assert math.hypot(z + 0.004, x - 0.008) == pytest.approx(0.004, abs=1e-12)  # on the circle
    for (z0, x0), (z1, x1) in zip(arc, arc[1:]):
        assert z1 <= z0  # still right to left
        mid = math.hypot((z0 + z1) / 2 + 0.004, (x0 + x1) / 2 - 0.008)
        assert 0.004 - mid <= 1e-6 + 1e-15  # chord error
    assert all(x >= 0.008 - 1e-15 for _, x in arc)


def test_turn_arc_with_negative_radius_is_concave():
    concave = parse_job(_arc_doc({"arc_to": [-4, 12], "radius": -4})).turn.profile
    mid = concave[len(concave) // 4]
    assert math.hypot(mid[0] - 0.0, mid[1] - 0.012) == pytest.approx(0.004, abs=1e-12)  # center (0, 12)


def test_turn_stock_may_hold_arcs_too():
    d = doc("turn")
    d["turn"]["stock"] = [[0, 18], {"arc_to": [-2, 20], "radius": 2}, [-40, 20]]
    stock = parse_job(d).turn.stock
    assert len(stock) > 4 and stock[-1] == [-0.04, 0.02]


@pytest.mark.parametrize("entry, field, words", [
    ({"arc_to": [-4, 12], "radius": 2}, "turn.profile[1].radius", ("shorter than half the chord", "2.828 mm")),
    ({"arc_to": [-4, 12], "center": [-4, 7]}, "turn.profile[1].center", ("not equally far",)),
    ({"arc_to": [-4, 12], "center": [-4, 8], "radius": 5}, "turn.profile[1].radius", ("does not match",)),
    ({"arc_to": [-4, 12]}, "turn.profile[1]", ("radius or a center",)),
    ({"arc_to": [0, 8], "radius": 4}, "turn.profile[1].arc_to", ("previous point",)),
    ({"arc_to": [-4, 12], "radius": "4"}, "turn.profile[1].radius", ("expected a number",)),
    ({"to": [-4, 12], "radius": 4}, "turn.profile[1].to", ("unknown key",)),
    ({"arc_to": [-4, 8], "center": [-2, 8]}, "turn.profile[1].center", ("half circle",)),
    ({"arc_to": [-1, 10 + math.sqrt(3)], "center": [0, 10]}, "turn.profile[1]", ("turns back in z",)),
    ("corner", "turn.profile[1]", ("[z, radius] point or an {arc_to",)),
])
def test_bad_turn_arcs_are_refused_at_their_path(entry, field, words):
    rejected(_arc_doc(entry), field, *words)


def test_turn_outline_cannot_start_with_an_arc():
    d = doc("turn")
    d["turn"]["profile"] = [{"arc_to": [-4, 12], "radius": 4}, [-40, 12]]
    rejected(d, "turn.profile[0]", "needs a point before it")
