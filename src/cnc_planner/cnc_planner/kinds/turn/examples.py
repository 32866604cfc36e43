"""Example stocks and profiles for rough turning, shared by tests, jobs and benchmarks.

Each entry has the keys of a job's `turn:` section, in the job's units: points are
[z, radius] in mm, right to left, face at z = 0; lengths mm, feed mm/rev.
The stocks are the cases the method is for: a plain bar (nothing to save), a pre-turned
cone, a stepped bar and a casting-like wavy outline with stock on the face. The cone's
and the casting's profiles have grooves, so their radius falls and rises again.
"""
from __future__ import annotations

from cnc_msgs_py.units import mm

_CUT = {"depth_of_cut": 1.5, "clearance": 0.5, "feed": 0.15, "origin": [5.0, 25.0], "finish_allowance": 0.2,
        "finish_allowance_z": 0.1}

EXAMPLES: dict[str, dict] = {
    "cylinder": {
        "stock": [[0.0, 20.0], [-40.0, 20.0]],
        "profile": [[0.0, 8.0], [-10.0, 8.0], [-10.0, 14.0], [-40.0, 14.0]],
        **_CUT,
    },
    "cone": {  # pre-turned cone; the profile has a square groove
        "stock": [[0.0, 10.0], [-30.0, 20.0], [-50.0, 20.0]],
        "profile": [[0.0, 6.0], [-5.0, 6.0], [-20.0, 12.0], [-26.0, 12.0], [-26.0, 9.0],
                    [-31.0, 9.0], [-31.0, 14.0], [-50.0, 14.0]],
        **_CUT,
    },
    "stepped": {  # bar turned in steps before; the profile has a chamfer and a taper
        "stock": [[0.0, 12.0], [-15.0, 12.0], [-15.0, 16.0], [-30.0, 16.0], [-30.0, 20.0], [-50.0, 20.0]],
        "profile": [[0.0, 7.0], [-1.0, 8.0], [-15.0, 8.0], [-18.0, 11.0], [-30.0, 11.0], [-30.0, 15.0],
                    [-50.0, 15.0]],
        **_CUT,
    },
    "casting": {  # wavy skin with 1 mm on the face; the profile has a groove with sloped walls
        "stock": [[1.0, 13.0], [0.0, 15.5], [-2.0, 15.9], [-4.0, 16.7], [-6.0, 17.3], [-8.0, 17.8],
                  [-10.0, 19.3], [-12.0, 17.7], [-14.0, 16.9], [-16.0, 16.8], [-18.0, 16.1],
                  [-20.0, 18.2], [-22.0, 18.7], [-24.0, 18.0], [-26.0, 18.1], [-28.0, 16.1],
                  [-30.0, 16.4], [-32.0, 17.6], [-34.0, 17.7], [-36.0, 19.1], [-38.0, 18.0],
                  [-40.0, 16.6], [-42.0, 16.9], [-44.0, 16.2], [-46.0, 17.9], [-48.0, 19.0],
                  [-50.0, 17.9], [-52.0, 18.0], [-54.0, 16.4], [-56.0, 16.0], [-58.0, 17.8],
                  [-60.0, 17.8]],
        "profile": [[0.0, 9.0], [-12.0, 9.0], [-14.0, 6.0], [-20.0, 6.0], [-22.0, 11.0], [-40.0, 11.0],
                    [-43.0, 14.0], [-60.0, 14.0]],
        **_CUT,
    },
}


def roughing_args(name: str) -> dict:
    """The example as SI keyword arguments of turning.plan_roughing / plan_naive."""
    ex = EXAMPLES[name]
    return {
        "stock": [(mm(z), mm(r)) for z, r in ex["stock"]],
        "profile": [(mm(z), mm(r)) for z, r in ex["profile"]],
        "depth_of_cut": mm(ex["depth_of_cut"]),
        "clearance": mm(ex["clearance"]),
        "origin": (mm(ex["origin"][0]), mm(ex["origin"][1])),
        "finish_allowance": mm(ex["finish_allowance"]),
        "finish_allowance_z": mm(ex["finish_allowance_z"]),
    }
