"""RS274/NGC as a language (cnc_msgs_py.gcode): parameters, expressions and O-word control
flow read as LinuxCNC 2.9 reads them, and the programs they make translated into our jobs.

The expected values are LinuxCNC's documented semantics (precedence levels, MOD's sign,
EQ's tolerance, degrees, ROUND's halves), each written out by hand.
"""
from __future__ import annotations

import math

import pytest

from cnc_msgs_py.gcode import Context, GcodeError, translate
from cnc_msgs_py.gcode.expressions import Reader, read_expression
from cnc_msgs_py.gcode.parameters import Parameters


def _params() -> Parameters:
    def none(name):
        raise AssertionError(name)
    return Parameters(none, none)


def value(text: str, params: Parameters | None = None) -> float:
    r = Reader("".join(text.split()).upper())
    expr = read_expression(r)
    assert r.done()
    return expr(params or _params())


@pytest.mark.parametrize("text,expected", [
    ("[1 + 2 * 3]", 7.0),                     # * over +
    ("[2 ** 3 * 2]", 16.0),                   # ** over *
    ("[2 ** 3 ** 2]", 64.0),                  # left to right within a level
    ("[10 - 4 - 3]", 3.0),
    ("[12 / 4 / 3]", 1.0),
    ("[1 + 1 EQ 2]", 1.0),                    # + over EQ
    ("[1 EQ 1 AND 0]", 0.0),                  # EQ over AND
    ("[1 LT 2 OR 0]", 1.0),
    ("[1 XOR 1]", 0.0), ("[1 XOR 0]", 1.0), ("[0 OR 0]", 0.0), ("[2 AND 3]", 1.0),
    ("[-7 MOD 3]", 2.0),                      # fmod, then + |b| when negative
    ("[7 MOD -3]", 1.0),
    ("[7.5 MOD 2]", 1.5),
    ("[1 EQ 1.00005]", 1.0),                  # within TOLERANCE_EQUAL
    ("[1 NE 1.0002]", 1.0),
    ("[2 GE 2]", 1.0), ("[2 GT 2]", 0.0), ("[2 LE 1]", 0.0),
    ("[SIN[30]]", 0.5), ("[COS[60]]", 0.5), ("[TAN[45]]", 1.0),
    ("[ASIN[1]]", 90.0), ("[ACOS[0]]", 90.0),
    ("[ATAN[1]/[-1]]", 135.0),                # atan2, degrees
    ("[SQRT[16] + ABS[-2]]", 6.0),
    ("[EXP[0] + LN[1]]", 1.0),
    ("[FIX[-2.5]]", -3.0), ("[FUP[-2.5]]", -2.0), ("[FIX[2.7]]", 2.0), ("[FUP[2.1]]", 3.0),
    ("[ROUND[2.5]]", 3.0), ("[ROUND[-2.5]]", -3.0), ("[ROUND[2.49]]", 2.0),
    ("[-[2 + 1] * 2]", -6.0),                 # unary minus on an expression
    ("[-SIN[90]]", -1.0),
    ("[1.5E1]", None),                        # no exponent notation in RS274/NGC
])
def test_expressions_evaluate_as_linuxcnc(text, expected):
    if expected is None:
        with pytest.raises(ValueError):
            value(text)
        return
    assert value(text) == pytest.approx(expected, abs=1e-12)


@pytest.mark.parametrize("text,reason", [
    ("[1 / 0]", "division by zero"),
    ("[SQRT[-1]]", "negative"),
    ("[LN[0]]", "not > 0"),
    ("[ACOS[2]]", "outside -1..1"),
    ("[[-8] ** 0.5]", "non-integer power"),
    ("[ATAN[1]]", "ATAN[y]/[x]"),
    ("[1 + ]", "expected a number"),
    ("[FOO[1]]", "not a function"),
])
def test_bad_expressions_say_why(text, reason):
    with pytest.raises(ValueError, match=re_escape(reason)):
        value(text)


def re_escape(text: str) -> str:
    import re
    return re.escape(text)


def test_numbered_and_named_parameters():
    p = _params()
    assert value("[#7]", p) == 0.0  # numbered: 0 until written
    p.write(7, 2.5)
    p.write("depth", 3.0)
    p.write("_global", 4.0)
    assert value("[#7 * #<depth> + #<_GLOBAL>]", p) == pytest.approx(11.5)
    with pytest.raises(ValueError, match="no such parameter"):
        value("[##8]", p)  # #8 is 0, and #0 does not exist
    p.write(8, 7.0)
    assert value("[##8]", p) == 2.5  # indirection: #[#8]
    assert value("[EXISTS[#<depth>] + EXISTS[#<nope>]]", p) == 1.0
    p.call([1.0, 2.0])  # a subroutine: #1-#30 its arguments, fresh locals, the globals shared
    assert (value("[#1 + #2 + #3]", p), value("[EXISTS[#<depth>]]", p), value("[#<_global>]", p)) == (3.0, 0.0, 4.0)
    p.ret(42.0)
    assert (value("[#1]", p), value("[#<depth>]", p), value("[#<_value>]", p)) == (0.0, 3.0, 42.0)


@pytest.mark.parametrize("target,reason", [
    (5221, "var file"), (5400, "read only"), (5420, "read only"), (0, "no such parameter"), (5602, "no such parameter")])
def test_parameters_a_program_cannot_write(target, reason):
    with pytest.raises(ValueError, match=reason):
        _params().write(target, 1.0)


# --- programs ----------------------------------------------------------------------------
def ops(text: str, machine: str = "mill3", **ctx) -> list:
    return [op.doc for op in translate(text, Context(job_id="t", machine=machine, **ctx))]


def moves(text: str, **ctx) -> list[dict]:
    return [m for doc in ops(text, **ctx) if doc["kind"] == "move" for m in doc["move"]]


def test_a_line_reads_before_it_writes():
    text = "G21 G90\n#1=1\n#1=2 #2=#1\nG0 X#1 Y#2 Z0\nM2"
    assert moves(text) == [{"rapid": {"x": 2.0, "y": 1.0, "z": 0.0}}]


def test_system_parameters_read_the_interpreters_state():
    text = """G20 G90 G17
G0 X1 Y2 Z0.5
#<a> = [#<_x> + #5421 * 10 + #<_metric> * 100 + #<_imperial> * 1000 + #<_absolute> * 10000]
G0 X#<a>
M2"""
    assert moves(text)[-1]["rapid"]["x"] == pytest.approx((1 + 20 + 0 + 1000 + 10000) * 25.4)
    with pytest.raises(GcodeError, match=r"^line 2: #<_z>: the Z position is unknown here"):
        ops("G21 G90\nG0 X#<_z>\nM2")


def test_a_bolt_circle_from_a_while_loop():
    text = """G21 G90 G17
M3 S3000
G0 X0 Y0 Z5
#<n> = 6
#<r> = 20
#<i> = 0
o100 while [#<i> LT #<n>]
  #<a> = [360 * #<i> / #<n>]
  G99 G81 X[#<r> * COS[#<a>]] Y[#<r> * SIN[#<a>]] Z-3 R2 F600
  #<i> = [#<i> + 1]
o100 endwhile
G80
M2"""
    (_, drill), = [ops(text)[:2]]
    holes = drill["drill"]["holes"]
    assert len(holes) == 6
    for k, (x, y) in enumerate(holes):
        assert (x, y) == pytest.approx((20 * math.cos(math.radians(60 * k)), 20 * math.sin(math.radians(60 * k))))


def test_a_hole_pattern_from_a_subroutine_with_arguments_and_a_returned_value():
    text = """G21 G90 G17
M3 S3000
G0 X0 Y0 Z5
o<row> sub
  (#1 x0, #2 y, #3 pitch, #4 count)
  #<k> = 0
  o101 repeat [#4]
    G98 G81 X[#1 + #<k> * #3] Y#2 Z-4 R1 F500
    #<k> = [#<k> + 1]
  o101 endrepeat
  G80
o<row> endsub [#4 * #3]
o<row> call [0] [0] [10] [3]
#<width> = #<_value>
o<row> call [0] [15] [12.5] [2]
G0 X#<width>
M2"""
    docs = ops(text)
    holes = [h for d in docs if d["kind"] == "drill" for h in d["drill"]["holes"]]
    assert holes == [[0.0, 0.0], [10.0, 0.0], [20.0, 0.0], [0.0, 15.0], [12.5, 15.0]]
    assert moves(text)[-1] == {"rapid": {"x": 30.0, "y": 15.0, "z": 5.0}}


def test_if_elseif_else_do_while_break_continue():
    text = """G21 G90
G0 X0 Y0 Z0
#1 = 0
o1 do
  #1 = [#1 + 1]
  o2 if [#1 EQ 2]
    o1 continue
  o2 elseif [#1 EQ 5]
    o1 break
  o2 else
    G0 X#1
  o2 endif
o1 while [#1 LT 100]
o3 if [0]
  G0 Y100
o3 endif
M2"""
    assert [m["rapid"]["x"] for m in moves(text)[1:]] == [1.0, 3.0, 4.0]


def test_a_subroutine_in_its_own_file_is_found_by_name():
    text = "G21 G90 G17\nM3 S2000\nG0 X0 Y0 Z5\no<peck> call [7] [-6]\nM2"
    files = {"peck": "o<peck> sub\n  G98 G83 X#1 Y0 Z#2 R1 Q2 F300\n  G80\no<peck> endsub\nM2\n"}
    drill, = [d for d in ops(text, subroutines=files) if d["kind"] == "drill"]
    assert drill["drill"]["holes"] == [[7.0, 0.0]] and drill["drill"]["peck"]["depth"] == 2.0
    bad = {"peck": "o<peck> sub\n  G1 X1\no<peck> endsub\n"}
    with pytest.raises(GcodeError, match=r"^line 4: peck.ngc: line 2: G1: no feed given"):
        ops(text, subroutines=bad)
    with pytest.raises(GcodeError, match=r"^line 4: o<peck> call: no such subroutine"):
        ops(text)


@pytest.mark.parametrize("text,reason", [
    ("G21\no1 sub\no1 call\no1 endsub\no1 call\nM2", "line 3: o1 call: calls nest deeper than 50"),
    ("G21\no1 repeat [1e3]\nM2", "line 2: E: expected an operator"),
    ("G21\no1 if [1]\no2 endif\nM2", "line 3: o2 endif: no open o2 if"),
    ("G21\no1 break\nM2", "line 2: o1 break: not inside an o1 loop"),
    ("G21\no1 while [1]\nG0 X1\no1 endwhile\nM2", "line 4: o1 endwhile: loops jumped back 100000 times"),
    ("G21\no1 return\nM2", "line 2: o1 return: not inside a subroutine"),
    ("G21\nG0 X#<_ini[axis_x]max_limit>\nM2", "line 2: #<_ini[axis_x]max_limit>: reads the machine's INI"),
    ("G21\n#5221=1\nM2", "line 2: #5221: LinuxCNC keeps it in its var file"),
])
def test_runaway_and_malformed_control_flow_is_refused_at_its_line(text, reason):
    with pytest.raises(GcodeError) as err:
        ops(text)
    assert str(err.value).startswith(reason), str(err.value)


def test_linuxcncs_own_forms_return_by_any_number_percent_ends_full_circles_g64_p():
    """As LinuxCNC's example programs write them: ``return`` inside an ``if`` with that if's
    number, a program closed by ``%`` without M2, a full circle by I/J alone, G64 P Q."""
    text = """%
G21 G90 G17 G64 P0.01 Q0.01
o1000 sub
  o1010 if [#1 GT 0]
    o1010 return [123 * #1]
  o1010 endif
o1000 endsub [4712]
o1000 call [2]
G0 X[#<_value> / 246] Y0 Z0
o1000 call [0]
G0 Y[#<_value> / 4712]
G2 I1 J0 F100
%
G0 X99
"""
    assert moves(text) == [{"rapid": {"x": 1.0, "y": 0.0, "z": 0.0}}, {"rapid": {"x": 1.0, "y": 1.0, "z": 0.0}}]
    circle = next(doc["path"] for doc in ops(text) if doc["kind"] == "path")  # G64 P: run on within P
    assert circle["chord_tolerance"] == 0.01 and circle["points"][0] == [1.0, 1.0, 0.0]
    assert circle["points"][-1] == [1.0, 1.0, 0.0]  # back at the start: a full circle, then %
    assert len(circle["points"]) > 10


def test_polar_words_about_the_origin():
    """LinuxCNC's hole-circle.ngc with the spindle on: G91 ^60 L6 steps round the origin;
    rs274 -g drills (0.75, 1.299), (-0.75, 1.299), (-1.5, 0), ... (inches, 4 decimals)."""
    text = "G20 G17 G90\nM3 S1000\nG0 X1.5 Y0 Z0\nG91 G81 R.1 Z-.5 ^60 L6 F10\nG90 G80\nG0 @2 ^90\nG91 G0 @-1 ^90\nM2"
    docs = ops(text)
    holes = docs[1]["drill"]["holes"]
    want = [(0.75, 1.299), (-0.75, 1.299), (-1.5, 0.0), (-0.75, -1.299), (0.75, -1.299), (1.5, 0.0)]
    assert [(round(x / 25.4, 4), round(y / 25.4, 4)) for x, y in holes] == want
    after = [m["rapid"] for m in moves(text)[-2:]]
    assert (after[0]["x"], after[0]["y"]) == pytest.approx((0.0, 2 * 25.4))
    assert (after[1]["x"], after[1]["y"]) == pytest.approx((-25.4, 0.0))
    with pytest.raises(GcodeError, match=r"^line 2: @: polar words cannot share a line with X or Y"):
        ops("G21 G90 G17\nG0 X1 @2\nM2", start={"x": 0.0, "y": 0.0})


def test_arcs_in_the_yz_plane():
    """G19: arcs in Y and Z by J and K, clockwise as seen from +X (LinuxCNC's 3dtest.ngc
    draws its YZ circle so)."""
    text = "G21 G90 G19\nG0 X5 Y0 Z0\nG2 Y2 Z0 J1 K0 F100\nM2"
    points = [m["linear"] for m in moves(text)[1:]]
    assert all(p["x"] == 5.0 for p in points) and points[-1] == {"x": 5.0, "y": 2.0, "z": 0.0}
    top = max(points, key=lambda p: p["z"])
    assert top["z"] == pytest.approx(1.0, abs=1e-3) and top["y"] == pytest.approx(1.0, abs=0.05)
    assert all(math.hypot(p["y"] - 1.0, p["z"]) == pytest.approx(1.0, abs=1e-9) for p in points)


@pytest.mark.parametrize("machine, reason", [
    ("mill3", "machine 'mill3' has no B axis (its axes: X, Y, Z)"),  # the machine is the cause
    ("lathe", "machine 'lathe' has no B axis (its axes: X, Z)"),
    ("5ax_head_table", "only X, Y and Z axis words are supported"),  # it has B: the front end is
])
def test_a_rotary_axis_word_is_refused_for_the_machine_that_lacks_it(machine, reason):
    with pytest.raises(GcodeError) as err:
        translate("G0 X0 Z1\nG0 B90\nM2\n", Context("rotary", machine))
    assert str(err.value) == f"line 2: B90: {reason}"
