"""The report page's verdicts for every report section, without a run or a browser."""
from __future__ import annotations

import base64
import re

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from cnc_planner.report_page import render, verdicts, write_report_page  # noqa: E402

BASE = {"job_id": "j1", "state": "succeeded", "reason": "", "cycle_time_s": 12.5, "planned_time_s": 12.7,
        "max_following_error": {"x": 1.8e-4, "z": 1.7e-4, "spindle": 0.015}, "setpoints": 12700, "chunks": 127,
        "chunks_lost": 0, "feedback_samples": 13000, "alarms": []}


def cards(report: dict) -> dict[str, tuple[str, str, str]]:
    return {title: (value, detail, cls) for title, value, detail, cls in verdicts(report)}


def test_rejected_job_page_says_why_and_nothing_else(tmp_path):
    report = {"job_id": "bad", "state": "rejected", "reason": "drill.depth: must be > 0 mm, got -5",
              "cycle_time_s": 0.0, "max_following_error": {}, "setpoints": 0, "chunks": 0, "chunks_lost": 0}
    page = write_report_page(report, [], tmp_path / "report.html")
    text = page.read_text()
    assert "REJECTED" in text and "drill.depth: must be &gt; 0 mm, got -5" in text
    assert list(cards(report)) == ["Job"] and cards(report)["Job"][2] == "bad"
    assert "<img" not in text


def test_chip_breaking_thread_and_turning_verdicts():
    aircut = {**BASE, "aircut": {"revolutions": 118, "revolutions_with_aircut": 118, "max_chip_revs": 0.94,
                                 "commanded": {"max_chip_revs": 0.96},
                                 "verdict": {"passed": True, "criterion": "chips", "says": "0.94 rev"}}}
    assert cards(aircut)["Chip breaking"][0] == "broken" and cards(aircut)["Chip breaking"][2] == "ok"
    # one vibration every 3 revolutions: an air-cut in a third of them, chips within the window
    aircut["aircut"].update(revolutions_with_aircut=40, max_chip_revs=2.43)
    assert cards(aircut)["Chip breaking"][:3:2] == ("broken", "ok")
    aircut["aircut"]["verdict"] = {"passed": False, "criterion": "chips", "says": "1 of 1 vibrated feeds ..."}
    assert cards(aircut)["Chip breaking"][2] == "bad"
    aircut["aircut"].update(revolutions=0, revolutions_with_aircut=0, max_chip_revs=0.0,
                            verdict={"passed": True, "criterion": "chips", "says": ""})
    assert cards(aircut)["Chip breaking"][:3:2] == ("not judged", "info")

    thread = {**BASE, "thread": {"chips_broken": False, "max_chip_revs": 7.5, "cutting_passes": 6,
                                 "full_depth": True, "depth_error_mm": 0.0, "overcut_mm": 0.0002,
                                 "helix_residual_mm": 0.0003, "doc_never_grows": True,
                                 "passes": [{"index": 0, "depth_mm": 0.44, "doc_mm": 0.44, "max_chip_revs": 7.5,
                                             "aircut_share": 0.0}]}}
    c = cards(thread)
    assert c["Chip breaking"][0] == "long chips" and c["Thread depth"][0] == "full depth"
    assert "Thread passes" in render(thread, [])

    turn = {**BASE, "turn": {"passes": 8, "air_feed_mm": 4.0, "naive_air_feed_mm": 109.0, "path_mm": 387.0,
                             "naive_path_mm": 540.0, "max_gouge_mm": 0.005, "max_gouge_part_mm": 0.005,
                             "max_gouge_commanded_mm": 0.0, "cycle_time_s": 12.5,
                             "verdict": {"passed": True, "criterion": "gouge", "says": "no gouge"}}}
    assert cards(turn)["Stock left / gouge"][0] == "no gouge"
    turn["turn"]["max_gouge_part_mm"] = 0.2
    turn["turn"]["verdict"] = {"passed": False, "criterion": "gouge", "says": "gouge: 0.2000 mm"}
    assert cards(turn)["Stock left / gouge"][2] == "bad"
    assert cards(turn)["Verdict on feedback"] == ("failed: turn", "turn: gouge: 0.2000 mm", "bad")


def test_cycle_time_against_conventional_and_lower_bound():
    drill = {**BASE, "drill": {"holes": [], "safety_violations": 0, "cycle_time_s": 3.0,
                               "conventional_cycle_time_s": 3.3, "lower_bound_s": 2.5}}
    value, detail, cls = cards(drill)["Cycle time"]
    assert value == "3.00 s" and cls == "ok"
    assert "9.1 % faster than conventional 3.30 s" in detail and "1.20 x the lower bound 2.50 s" in detail
    assert cards(drill)["Safety"][2] == "ok"
    drill["drill"]["safety_violations"] = 2
    assert cards(drill)["Safety"] == ("2 violations", cards(drill)["Safety"][1], "bad")
    assert cards({**BASE, "chunks_lost": 1})["Setpoints"][2] == "bad"


def test_plots_are_embedded_in_order_with_captions(tmp_path):
    paths = []
    for name in ("following_error", "turn_passes"):
        fig, ax = plt.subplots(figsize=(2, 2))
        ax.plot([0, 1], [0, 1])
        paths.append(tmp_path / f"{name}.png")
        fig.savefig(paths[-1])
        plt.close(fig)
    text = render(BASE, paths)
    sources = re.findall(r'<img src="data:image/png;base64,([^"]+)"', text)
    assert [base64.b64decode(s) for s in sources] == [paths[1].read_bytes(), paths[0].read_bytes()]
    assert "Roughing passes over the stock outline" in text and "following error" in text
    assert "<script" not in text and "http" not in text


def test_every_value_from_the_report_is_escaped():
    report = {**BASE, "job_id": "<script>x</script>", "alarms": ["limit <X+>"],
              "drill": {"holes": [{"index": 0, "mode": "<b>arc</b>"}, {"index": None}], "safety_violations": 0}}
    text = render(report, [], job={"kind": "drill", "machine": "<mill>"})
    assert "<script" not in text and "&lt;script&gt;x&lt;/script&gt;" in text
    assert "alarms: limit &lt;X+&gt;" in text and "<td>&lt;b&gt;arc&lt;/b&gt;</td>" in text
    assert "machine &lt;mill&gt;" in text
    assert "<tr><td></td><td></td>" in text  # a hole without figures: empty cells, not 'None'


def test_a_long_table_shows_its_first_rows_and_folds_the_rest():
    """A plate's holes table: the first rows on the page, all of them behind one click."""
    from cnc_planner.report_page import FOLD_ROWS, SHOWN_ROWS

    holes = [{"index": i, "x_mm": float(i), "y_mm": 0.0, "depth_mm": 5.0, "mode": 1} for i in range(FOLD_ROWS + 5)]
    report = {"job_id": "plate", "state": "succeeded", "reason": "", "cycle_time_s": 1.0, "max_following_error": {},
              "setpoints": 1, "chunks": 1, "chunks_lost": 0,
              "drill": {"holes": holes, "safety_violations": 0, "cycle_time_s": 1.0}}
    html = render(report, [])
    folded = re.search(r'<details class="fold"><summary>all (\d+) rows</summary>(.*?)</details>', html, re.S)
    assert folded and int(folded.group(1)) == FOLD_ROWS + 5
    before = html[:folded.start()]
    assert before.count("<tr><td>") == SHOWN_ROWS and folded.group(2).count("<tr><td>") == FOLD_ROWS + 5
    holes[FOLD_ROWS:] = []
    assert '<details class="fold">' not in render(report, [])
