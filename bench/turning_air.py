"""How much air feed the short-air-move roughing saves against passes started at the virtual cylinder.

For every example stock in cnc_planner.kinds.turn.examples: passes, air feed and path length
of plan_roughing against plan_naive. Prints the table, writes it to
bench/results/turning_air.txt and draws stock, profile and pass pattern of each example
to bench/results/turning_passes.png.

    /tmp/venv/bin/python bench/turning_air.py
"""
from __future__ import annotations

import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(REPO / "src" / "cnc_msgs_py"), str(REPO / "src" / "cnc_planner")]

import matplotlib  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from cnc_msgs_py.units import to_mm  # noqa: E402
from cnc_planner.kinds.turn.roughing import RoughingPlan, plan_naive, plan_roughing  # noqa: E402
from cnc_planner.kinds.turn.examples import EXAMPLES, roughing_args  # noqa: E402
from publish import RESULTS, write_result  # noqa: E402



def saving(ours: float, naive: float) -> str:
    return f"{100.0 * (naive - ours) / naive:.1f}" if naive > 0.0 else "-"


def table(plans: dict[str, tuple[RoughingPlan, RoughingPlan]]) -> str:
    head = (f"{'stock':<9} {'passes':>6} {'air ours':>9} {'air naive':>9} {'saving %':>8} "
            f"{'path ours':>9} {'path naive':>10} {'saving %':>8}")
    lines = [head, "-" * len(head)]
    for name, (ours, naive) in plans.items():
        air, air_n = to_mm(ours.air_feed_length), to_mm(naive.air_feed_length)
        path, path_n = to_mm(ours.path_length), to_mm(naive.path_length)
        lines.append(f"{name:<9} {ours.passes:>6} {air:>9.1f} {air_n:>9.1f} {saving(air, air_n):>8} "
                     f"{path:>9.1f} {path_n:>10.1f} {saving(path, path_n):>8}")
    lines.append("lengths in mm; air = feed-rate travel not touching the stock left at that moment")
    return "\n".join(lines)


def draw(plans: dict[str, tuple[RoughingPlan, RoughingPlan]], path: Path) -> None:
    fig, axes = plt.subplots(len(plans), 1, figsize=(10, 3.6 * len(plans)))
    for ax, (name, (ours, naive)) in zip(axes, plans.items()):
        ex = EXAMPLES[name]
        stock, profile = ex["stock"], ex["profile"]
        ax.fill([p[0] for p in stock] + [stock[-1][0], stock[0][0]], [p[1] for p in stock] + [0, 0],
                color="#d9d9d9", label="stock")
        ax.fill([p[0] for p in profile] + [profile[-1][0], profile[0][0]], [p[1] for p in profile] + [0, 0],
                color="#7f7f7f", label="profile")
        for (a, m), touched in zip(ours.segments(), ours.engagement()):
            z, x = [to_mm(a[0]), to_mm(m.z)], [to_mm(a[1]), to_mm(m.x)]
            if m.kind == "rapid":
                ax.plot(z, x, ":", color="#ff7f0e", lw=0.9)
            else:
                ax.plot(z, x, "-", color="#1f77b4" if touched > 0.0 else "#d62728", lw=1.4)
        starts = [a for (a, m), (_, prev) in zip(ours.segments()[1:], ours.segments()) if m.kind == "feed"
                  and prev.kind == "rapid"]
        ax.plot([to_mm(p[0]) for p in starts], [to_mm(p[1]) for p in starts], "o", ms=3, color="#1f77b4")
        ax.plot(*ex["origin"], "k^", ms=6)
        ax.annotate("Q0", ex["origin"], textcoords="offset points", xytext=(5, -4))
        ax.set_title(f"{name}: {ours.passes} passes, air feed {to_mm(ours.air_feed_length):.1f} mm "
                     f"(naive {to_mm(naive.air_feed_length):.1f} mm)")
        ax.set_aspect("equal")
        ax.set_xlabel("z [mm]")
        ax.set_ylabel("x (radius) [mm]")
        ax.set_ylim(0, ex["origin"][1] + 2)
        ax.grid(alpha=0.3)
    handles = [plt.Line2D([], [], color="#1f77b4", lw=1.4, label="feed, cutting"),
               plt.Line2D([], [], color="#d62728", lw=1.4, label="feed entirely in air"),
               plt.Line2D([], [], color="#ff7f0e", ls=":", label="rapid"),
               plt.Line2D([], [], color="#1f77b4", marker="o", ls="", ms=3, label="pass start")]
    handles = axes[0].get_legend_handles_labels()[0] + handles
    fig.legend(handles=handles, loc="upper center", ncol=len(handles), fontsize=9, frameon=False)
    fig.tight_layout(rect=(0, 0, 1, 0.98))
    fig.savefig(path, dpi=110)


def main() -> None:
    plans = {}
    for name in EXAMPLES:
        args = roughing_args(name)
        plans[name] = (plan_roughing(**args), plan_naive(**args))
    text = table(plans)
    print(text)
    write_result("turning_air.txt", text)
    draw(plans, RESULTS / "turning_passes.png")


if __name__ == "__main__":
    main()
