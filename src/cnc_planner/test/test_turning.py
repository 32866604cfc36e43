"""Rough turning with short air moves: geometry checked by replaying the path against the stock."""
from __future__ import annotations

import math
import re

import numpy as np
import pytest

from cnc_msgs_py.outline import ArcError, arc_points
from cnc_msgs_py.schema import JobError
from cnc_msgs_py.units import mm
from cnc_planner.kinds.turn.judge import material_left, max_gouge
from cnc_planner.kinds.turn.moves import RoughingPlan
from cnc_planner.kinds.turn.outline import TurningError, check_outlines, offset_outline
from cnc_planner.kinds.turn.roughing import plan_naive, plan_roughing
from cnc_planner.kinds.turn.stock import StockModel
from cnc_planner.kinds.turn.examples import EXAMPLES, roughing_args

NAMES = list(EXAMPLES)
SAMPLE_STEP = mm(0.01)  # tool tip samples along the path for the gouge check
GEOM_TOL = 1.0e-9  # m


def plans(name: str, **extra) -> tuple[dict, RoughingPlan, RoughingPlan]:
    args = roughing_args(name)
    return args, plan_roughing(**args, **extra), plan_naive(**args, **extra)


def pass_starts(plan: RoughingPlan) -> list[tuple[tuple[float, float], StockModel]]:
    """Each point where a feed begins after a rapid, with a copy of the stock left at that moment."""
    model = StockModel(plan.stock)
    out, previous = [], None
    for a, m in plan.segments():
        if m.kind == "feed" and (previous is None or previous.kind == "rapid"):
            snapshot = StockModel(plan.stock)
            snapshot.field = model.field
            out.append((a, snapshot))
        model.cut(a, m.end)
        previous = m
    return out


# --- hand-computed cylinder case (the DESIGN job: 20 mm bar, 8/14 mm shoulder) -------------

def test_cylinder_passes_by_hand():
    args, plan, _ = plans("cylinder")
    # r_max 20, d 1.5, floor 8 + 0.2: 18.5 17 15.5 14 12.5 11 9.5, then 8.2 (not 8.0)
    radii = [18.5, 17.0, 15.5, 14.0, 12.5, 11.0, 9.5, 8.2]
    assert plan.passes == len(radii)
    feeds = [(a, m) for a, m in plan.segments() if m.kind == "feed"]
    assert len(feeds) == len(radii)
    for (start, m), r in zip(feeds, radii):
        assert start == pytest.approx((mm(0.5), mm(r)), abs=1e-12)  # face + clearance
        # above the 14.2 mm offset shoulder the pass runs to the profile's end, below it to the shoulder
        # face plus the 0.1 mm axial allowance
        assert (m.z, m.x) == pytest.approx((mm(-40.0) if r > 14.2 else mm(-9.9), mm(r)), abs=1e-12)


def test_cylinder_path_length_by_hand():
    _, plan, _ = plans("cylinder")
    approach = math.hypot(5.0 - 0.5, 25.0 - 18.5)
    cuts = 3 * 40.5 + 5 * 10.4
    # retract 0.5 at 45 degrees, back in Z, down to the next pass (2.0 = d + clearance; 1.8 to the 8.2 floor)
    retract = math.sqrt(2.0) * 0.5
    links = 3 * (retract + 40.0 + 2.0) + 3 * (retract + 9.9 + 2.0) + (retract + 9.9 + 1.8)
    home = retract + math.hypot(5.0 + 9.4, 25.0 - 8.7)
    assert plan.path_length == pytest.approx(mm(approach + cuts + links + home), abs=1e-12)
    assert plan.feed_length == pytest.approx(mm(cuts), abs=1e-12)
    assert plan.air_feed_length == pytest.approx(mm(8 * 0.5), abs=1e-12)  # the clearance before each pass
    total = round(approach + cuts + links + home, 3)
    assert plan.to_dict() == {"passes": 8, "air_feed_mm": 4.0, "path_mm": total, "feed_mm": round(cuts, 3)}


def test_cylinder_same_as_naive():
    _, plan, naive = plans("cylinder")
    assert plan.air_feed_length == pytest.approx(naive.air_feed_length, abs=GEOM_TOL)
    assert plan.path_length == pytest.approx(naive.path_length, abs=GEOM_TOL)


# --- every example stock --------------------------------------------------------------------

@pytest.mark.parametrize("finishing", [False, True])
@pytest.mark.parametrize("name", NAMES)
def test_no_gouge(name, finishing):
    args, plan, naive = plans(name, finishing_pass=finishing)
    for p in (plan, naive):
        assert max_gouge(p.points(SAMPLE_STEP), args["profile"], args["finish_allowance"],
                         args["finish_allowance_z"]) <= GEOM_TOL


@pytest.mark.parametrize("name", NAMES)
def test_material_left_within_depth_of_cut(name):
    args, plan, _ = plans(name)
    left = material_left(args["stock"], args["profile"], plan.moves, args["origin"])
    assert left <= args["depth_of_cut"] + args["finish_allowance"] + GEOM_TOL or args["finish_allowance_z"] > 0.0
    # above the profile offset by both allowances, radially
    left = material_left(args["stock"], args["profile"], plan.moves, args["origin"], args["finish_allowance"],
                         args["finish_allowance_z"])
    assert left <= args["depth_of_cut"] + GEOM_TOL


@pytest.mark.parametrize("name", NAMES)
def test_finishing_pass_leaves_the_allowance(name):
    args, plan, _ = plans(name, finishing_pass=True)
    left = material_left(args["stock"], args["profile"], plan.moves, args["origin"], args["finish_allowance"],
                         args["finish_allowance_z"])
    assert left == pytest.approx(0.0, abs=GEOM_TOL)
    without_axial = {**args, "finish_allowance_z": 0.0}
    plan = plan_roughing(**without_axial, finishing_pass=True)
    left = material_left(args["stock"], args["profile"], plan.moves, args["origin"])
    assert left == pytest.approx(args["finish_allowance"], abs=GEOM_TOL)


@pytest.mark.parametrize("name", NAMES)
def test_passes_start_within_clearance_of_the_stock_left(name):
    args, plan, naive = plans(name)
    starts = pass_starts(plan)
    assert len(starts) >= plan.passes
    for (z, x), model in starts:
        assert x >= float(model.field.at(z)[0]) - GEOM_TOL  # in air, not inside
        assert model.distance((z, x)) <= args["clearance"] + GEOM_TOL
    if name != "cylinder":  # the baseline really starts far from the stock
        assert max(model.distance(p) for p, model in pass_starts(naive)) > 2 * args["clearance"]


@pytest.mark.parametrize("name", NAMES)
def test_rapids_touch_nothing_and_stay_in_the_zone(name):
    args, plan, _ = plans(name, finishing_pass=True)
    for (_, m), touched in zip(plan.segments(), plan.engagement()):
        if m.kind == "rapid":
            assert touched <= GEOM_TOL
        assert m.z >= args["profile"][-1][0] - GEOM_TOL


@pytest.mark.parametrize("name", NAMES)
def test_origin_moves_are_straight_and_links_are_z_then_x(name):
    args, plan, _ = plans(name)
    segs = plan.segments()
    first, last = segs[0], segs[-1]
    assert first[0] == args["origin"] and first[1].kind == "rapid" and segs[1][1].kind == "feed"
    assert last[1].end == args["origin"] and last[1].kind == "rapid"
    last_feed = max(i for i, (_, m) in enumerate(segs) if m.kind == "feed")
    alpha = args["clearance"]

    def is_retract(i: int) -> bool:  # 45 degrees up and right by the clearance, right after a feed
        a, m = segs[i]
        return (segs[i - 1][1].kind == "feed" and m.kind == "rapid"
                and (m.z - a[0], m.x - a[1]) == pytest.approx((alpha, alpha), abs=GEOM_TOL))

    # after the last pass: the retract, then straight home, or first a lift in X where the straight
    # line would hit a wall
    assert is_retract(last_feed + 1)
    assert len(segs) - last_feed - 2 in (1, 2)
    if len(segs) - last_feed - 2 == 2:
        assert segs[-2][0][0] == segs[-2][1].z
    for i, (a, m) in enumerate(segs[1:-1], start=1):
        if m.kind == "rapid" and not is_retract(i):
            assert a[0] == m.z or a[1] == m.x  # links run along one axis at a time


@pytest.mark.parametrize("name", [n for n in NAMES if n != "cylinder"])
def test_less_air_than_naive(name):
    _, plan, naive = plans(name)
    assert plan.passes == naive.passes
    assert plan.air_feed_length < naive.air_feed_length - mm(1.0)
    assert plan.path_length <= naive.path_length + GEOM_TOL


@pytest.mark.parametrize("finishing", [False, True])
@pytest.mark.parametrize("name", NAMES)
def test_rapids_stop_the_clearance_away_from_the_stock_left(name, finishing):
    """No rapid ends on a face or a surface: a servo overshoot of a few um at its end cuts nothing."""
    args, plan, naive = plans(name, finishing_pass=finishing)
    for p in (plan, naive):
        model = StockModel(p.stock)
        for a, m in p.segments()[:-1]:  # the last one ends at the origin
            model.cut(a, m.end)
            if m.kind == "rapid":
                assert model.distance(m.end) >= args["clearance"] - GEOM_TOL, (name, m)


@pytest.mark.parametrize("name", NAMES)
def test_the_tool_stays_the_axial_allowance_off_shoulder_faces(name):
    """Feeds end finish_allowance_z before a face: an overshoot in z on feedback stays in the allowance."""
    args, plan, _ = plans(name, finishing_pass=True)
    pts = plan.points(SAMPLE_STEP)
    assert max_gouge(pts, args["profile"], args["finish_allowance"], args["finish_allowance_z"]) <= GEOM_TOL
    # shifted 0.09 mm (< W = 0.1 mm) either way along z, the path is still clear of the part
    for dz in (-mm(0.09), mm(0.09)):
        assert max_gouge(pts + [dz, 0.0], args["profile"], 0.0) == 0.0
    # with W = 0 the passes end on the faces themselves (a shoulder, or the part's end face under
    # the casting's face stock): the same shift cuts into the part
    flat = plan_roughing(**{**args, "finish_allowance_z": 0.0})
    shifted = [max_gouge(flat.points(SAMPLE_STEP) + [dz, 0.0], args["profile"], 0.0) for dz in (-mm(0.09), mm(0.09))]
    assert max(shifted) == pytest.approx(mm(0.09), abs=GEOM_TOL)


def test_grooves_are_roughed_from_above():
    """The cone's square groove (z -26..-31, 9 mm) is cut below the 12 mm land to its right."""
    args, plan, _ = plans("cone")
    in_groove = [(a, m) for a, m in plan.segments()
                 if m.kind == "feed" and mm(-31.0) - GEOM_TOL <= m.z <= mm(-26.0) and m.x < mm(12.0)]
    assert in_groove
    ramps = [(a, m) for a, m in in_groove if a[1] > m.x]  # the tool comes down onto the material
    assert ramps
    for a, m in ramps:  # on a 45-degree-or-steeper ramp that starts the clearance off the groove's wall
        assert m.z - a[0] == pytest.approx(args["clearance"], abs=GEOM_TOL)
        assert m.z == pytest.approx(mm(-26.0 - 0.1), abs=GEOM_TOL)  # the wall, less the axial allowance


def test_dips_in_a_casting_are_crossed_at_rapid():
    args, plan, _ = plans("casting")
    top = max(r for _, r in args["stock"]) - args["depth_of_cut"]
    along = [m for a, m in plan.segments() if m.kind == "rapid" and a[1] == m.x == pytest.approx(top)]
    assert along


def test_nothing_to_cut_gives_an_empty_plan():
    stock = [(0.0, mm(10.0)), (mm(-20.0), mm(10.0))]
    plan = plan_roughing(stock, stock, mm(1.0), mm(0.5), (mm(5.0), mm(15.0)))
    assert plan.passes == 0 and plan.moves == [] and plan.path_length == 0.0


# --- geometric checks themselves --------------------------------------------------------------

def test_max_gouge_measures_depth_inside_profile_plus_allowance():
    profile = [(0.0, mm(8.0)), (mm(-10.0), mm(8.0)), (mm(-10.0), mm(14.0)), (mm(-40.0), mm(14.0))]
    pts = np.array([[mm(-5.0), mm(8.2)], [mm(-9.95), mm(9.0)], [mm(5.0), mm(1.0)], [mm(-5.0), mm(7.9)],
                    [mm(-10.05), mm(14.0)]])
    assert max_gouge(pts[:3], profile, mm(0.2)) == 0.0  # radial allowance: none on the shoulder face
    assert max_gouge(pts[:4], profile, mm(0.2)) == pytest.approx(mm(0.3))
    assert max_gouge(pts[4:], profile, mm(0.2)) == pytest.approx(mm(0.05))  # nearest way out: the face


def test_offset_outline_moves_diameters_and_faces():
    profile = [(0.0, mm(8.0)), (mm(-10.0), mm(8.0)), (mm(-10.0), mm(14.0)), (mm(-20.0), mm(14.0)),
               (mm(-20.0), mm(9.0)), (mm(-25.0), mm(9.0)), (mm(-30.0), mm(14.0)), (mm(-40.0), mm(14.0))]
    out = offset_outline(profile, mm(0.2), mm(0.1))
    # faces move away from the part both ways: the shoulder at -10 (facing right) to -9.9, the
    # groove's left wall at -20 (facing left) to -20.1, the right end face at 0 to 0.1; the slope
    # (-25, 9) -> (-30, 14), approached from the right, by the rectangle's corner: right 0.1, up 0.2
    want = [(0.1, 8.2), (-9.9, 8.2), (-9.9, 14.2), (-20.1, 14.2), (-20.1, 9.2), (-24.9, 9.2),
            (-29.9, 14.2), (-40.0, 14.2)]
    assert len(out) == len(want)
    for (z, x), (wz, wx) in zip(out, want):
        assert (z, x) == pytest.approx((mm(wz), mm(wx)), abs=1e-12)
    assert offset_outline(profile, mm(0.2), 0.0) == [(z, x + mm(0.2)) for z, x in profile]


def test_material_left_of_an_empty_path_is_the_whole_stock_above_the_profile():
    args = roughing_args("cylinder")
    assert material_left(args["stock"], args["profile"], [], args["origin"]) == pytest.approx(mm(12.0))


# --- validation -------------------------------------------------------------------------------

BAR = [(0.0, mm(20.0)), (mm(-40.0), mm(20.0))]


@pytest.mark.parametrize("stock, profile, message", [
    (BAR, [(0.0, mm(8.0)), (mm(-10.0), mm(8.0)), (mm(-10.0), mm(14.0)), (mm(-10.0), mm(12.0)),
           (mm(-40.0), mm(12.0))], "turn.profile: self-intersects at segment 2"),
    (BAR, [(0.0, mm(8.0)), (mm(-12.0), mm(8.0)), (mm(-12.0), mm(22.0)), (mm(-40.0), mm(22.0))],
     "turn.profile: lies outside the stock at z=-12.0 mm"),
    (BAR, [(0.0, mm(8.0)), (mm(-45.0), mm(8.0))], "turn.profile: lies outside the stock at z=-45.0 mm"),
    ([(0.0, mm(20.0)), (mm(-40.0), mm(20.0)), (mm(-30.0), mm(20.0))], BAR,
     "turn.stock: z must decrease from right to left (point 2)"),
    (BAR, [(0.0, mm(8.0)), (mm(-5.0), mm(-1.0)), (mm(-10.0), mm(8.0))],
     "turn.profile: radius must not be negative (point 1): only the outline's ends may run past the spindle axis"),
    (BAR, [(0.0, mm(-1.0)), (mm(-10.0), mm(-1.0))], "turn.profile: radius must not be negative (point 0)"),
    (BAR, [(0.0, mm(8.0)), (0.0, mm(8.0)), (mm(-10.0), mm(8.0))], "turn.profile: point 1 repeats point 0"),
    ([(0.0, mm(20.0))], BAR, "turn.stock: needs at least 2 points"),
    (BAR, [(0.0, 0.0), (0.0, mm(8.0))], "turn.profile: must span a length along z"),
])
def test_bad_outlines_are_rejected_in_one_line(stock, profile, message):
    with pytest.raises(TurningError) as err:
        check_outlines(stock, profile)
    assert str(err.value).startswith(message)
    assert "\n" not in str(err.value)


@pytest.mark.parametrize("change, message", [
    ({"depth_of_cut": 0.0}, "turn.depth_of_cut: must be a positive length (got 0.0 mm)"),
    ({"clearance": -mm(1.0)}, "turn.clearance: must be a positive length (got -1.0 mm)"),
    ({"finish_allowance": -mm(0.1)}, "turn.finish_allowance: must not be negative (got -0.1 mm)"),
    ({"origin": (mm(-20.0), mm(10.0))}, "turn.origin: must lie above the stock"),
])
def test_bad_parameters_are_rejected(change, message):
    args = {**roughing_args("cylinder"), **change}
    with pytest.raises(TurningError, match="^" + re.escape(message)):
        plan_roughing(**args)


def test_an_origin_whose_straight_move_would_cut_the_cone_goes_around_it():
    """Right of the face but below the cone: the first pass is reached as the others are, up
    clear of the stock first, and no rapid touches it."""
    args = {**roughing_args("cone"), "origin": (mm(5.0), mm(5.0))}
    plan = plan_roughing(**args)
    assert plan.moves[0].kind == "rapid" and plan.moves[0].z == mm(5.0) and plan.moves[0].x > mm(5.0)
    assert all(t == 0.0 for (_, m), t in zip(plan.segments(), plan.engagement()) if m.kind == "rapid")


def test_turning_error_is_a_job_error_that_names_the_field():
    args = {**roughing_args("cylinder"), "clearance": -mm(1.0)}
    with pytest.raises(JobError) as err:
        plan_roughing(**args)
    assert isinstance(err.value, TurningError)
    assert (err.value.field, err.value.reason) == ("turn.clearance", "must be a positive length (got -1.0 mm)")


# --- arcs -------------------------------------------------------------------------------------

def _chord_error(points, center, radius):
    pts = np.array(points)
    mids = (pts[1:] + pts[:-1]) / 2.0
    on_arc = np.abs(np.linalg.norm(pts - center, axis=1) - radius).max()
    return radius - np.linalg.norm(mids - center, axis=1).min(), on_arc


def test_arc_by_radius_within_chord_tolerance():
    start, end = (mm(0.0), mm(10.0)), (mm(-10.0), mm(20.0))
    pts = arc_points(start, end, radius=mm(10.0), max_chord_error=mm(0.001))
    assert pts[0] == start and pts[-1] == end
    sag, off = _chord_error(pts, np.array([mm(-10.0), mm(10.0)]), mm(10.0))
    assert 0.0 < sag <= mm(0.001) + 1e-15 and off < 1e-15
    assert all(b[0] <= a[0] for a, b in zip(pts, pts[1:]))  # still right to left


def test_arc_sign_positive_is_convex():
    """Run right to left, a positive radius bulges away from the axis, a negative one towards it."""
    start, end = (mm(0.0), mm(10.0)), (mm(-10.0), mm(20.0))
    chord_mid = (np.array(start) + np.array(end)) / 2.0
    convex = np.array(arc_points(start, end, radius=mm(10.0)))
    concave = np.array(arc_points(start, end, radius=-mm(10.0)))
    normal_out = np.array([1.0, 1.0]) / math.sqrt(2.0)  # away from the axis for this chord
    assert (convex[len(convex) // 2] - chord_mid) @ normal_out > 0.0
    assert (concave[len(concave) // 2] - chord_mid) @ normal_out < 0.0


def test_arc_by_center_and_half_circle():
    start, end, center = (mm(-10.0), mm(10.0)), (mm(-20.0), mm(10.0)), (mm(-15.0), mm(10.0))
    with pytest.raises(ArcError, match="half circle"):
        arc_points(start, end, center=center)
    bump = np.array(arc_points(start, end, center=center, radius=mm(5.0)))
    groove = np.array(arc_points(start, end, center=center, radius=-mm(5.0)))
    assert bump[:, 1].max() == pytest.approx(mm(15.0), abs=1e-6)
    assert groove[:, 1].min() == pytest.approx(mm(5.0), abs=1e-6)
    quarter = arc_points((0.0, mm(5.0)), (mm(-5.0), 0.0), center=(mm(-5.0), mm(5.0)))
    assert all(np.hypot(z + mm(5.0), x - mm(5.0)) == pytest.approx(mm(5.0)) for z, x in quarter)
    assert all(z + mm(5.0) >= -1e-15 and x - mm(5.0) <= 1e-15 for z, x in quarter)  # the short way round


def test_bad_arcs():
    with pytest.raises(ArcError, match="not equally far"):
        arc_points((0.0, 0.01), (-0.01, 0.02), center=(0.0, 0.0))
    with pytest.raises(ArcError, match="shorter than half the chord"):
        arc_points((0.0, 0.01), (-0.01, 0.02), radius=0.001)
