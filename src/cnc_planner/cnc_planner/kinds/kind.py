"""What a job kind is to the rest of the planner: the hooks a kind's folder fills in.

The executive, the segmenting, the report, the figures and the progress display look a
kind up in ``cnc_planner.kinds.KINDS`` and call these; none of them switches on a kind's
name. Everything but ``name`` and ``plan`` is optional: a kind without a report section
gets the sections every job gets (cycle time, following error, air-cuts of vibrated feeds).

A kind's report section, page and figures are named here as "module:function" and imported
on first use: the registry is what planning looks kinds up in, and planning must not load
the judge (cnc_analysis, rosbags), matplotlib or jinja2 with it (the planner node and
cnc-plan started in 0.5-1.5 s with them).
"""
from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass
from functools import cache
from types import SimpleNamespace
from typing import TYPE_CHECKING, Any

import numpy as np

from cnc_msgs_py.machine import Machine

from cnc_planner.kinematics import Kinematics
from cnc_planner.motion.builder import PlanBuilder

if TYPE_CHECKING:  # a type only: importing the recording would load the judge and rosbags with the registry
    from cnc_analysis.recording import Run


Job = SimpleNamespace  # a validated job document in SI units (cnc_msgs_py.job.parse_job)


@cache
def resolve(ref: str) -> Any:
    """What a "module:name" reference names, its module imported on first use."""
    module, _, name = ref.partition(":")
    return getattr(importlib.import_module(module), name)


@dataclass(frozen=True)
class Segmenting:
    """How a long job of this kind is planned in segments (cnc_planner.segments).

    Attributes:
        size: items (holes, moves) per segment.
        index: the event field that numbers items over the whole job.
        count: how many items the job has.
        part: the job with only its items lo..hi-1.
        check_whole: checks every item before the first segment (job, machine, kinematics,
            start position); what it returns is handed to ``prepare`` and ``settle``.
        prepare: the job as the segments cut it (e.g. holes put in their touring order).
        settle: called at the end of every segment but the last, so that the next one
            starts from drives at rest.
    """

    size: int
    index: str
    count: Callable[[Job], int]
    part: Callable[[Job, int, int], Job]
    check_whole: Callable[[Job, Machine, Kinematics, dict[str, float]], Any]
    prepare: Callable[[Job, Any], Job] | None = None
    settle: Callable[[PlanBuilder, Any, Kinematics], None] | None = None


Card = tuple[str, str, str, str]  # a verdict on the report page: title, value, detail, ok | bad | warn | info
Table = tuple[str, list[str], list[list]]  # a table on the report page: heading, column names, rows


@dataclass(frozen=True)
class ReportSection:
    """The kind's section of report.json: ``judge`` reads the recorded feedback in the job's
    window and returns the section under ``key`` (or None: nothing to judge, no section);
    ``cards`` and ``tables`` put it on the report page. Each is given as a "module:function"
    reference (``judge_at``, ``cards_at``, ``tables_at``) and imported when first called for."""

    key: str
    judge_at: str
    judges_chips: bool = False  # it judges its own air-cuts (else vibrated feeds get the aircut section)
    times_cycle: bool = False  # its cycle_time_s (and conventional / lower bound) is the page's cycle time
    cards_at: str | None = None
    tables_at: str | None = None
    # What ``judge`` compares the run with that depends only on (job, machine, start):
    # cnc_planner.baselines functions, which cnc-run computes while the job runs.
    baselines_at: tuple[str, ...] = ()

    @property
    def judge(self) -> Callable[[Run, Job, Machine, np.ndarray], dict | None]:
        return resolve(self.judge_at)

    @property
    def cards(self) -> Callable[[dict], list[Card]] | None:
        return resolve(self.cards_at) if self.cards_at else None

    @property
    def tables(self) -> Callable[[dict], list[Table]] | None:
        return resolve(self.tables_at) if self.tables_at else None


@dataclass(frozen=True)
class Figures:
    """The kind's PNG figures of a run, drawn when its report section is present, from its
    figures ``module``, imported when first asked for: matplotlib stays out of the nodes
    (it was a third of the planner's import time). The module's ``draw`` returns (figure,
    file name) pairs, its ``CAPTIONS`` say what the report page writes under each figure
    (file stem -> text), and its function ``aircut_summary``, if named, gives the air-cut
    summary the aircut figures show."""

    module: str
    aircut_summary: str | None = None

    @property
    def draw(self) -> Callable[[Run, Job, Machine, np.ndarray, dict], list[tuple[Any, str]]]:
        return resolve(f"{self.module}:draw")

    @property
    def captions(self) -> dict[str, str]:
        return resolve(f"{self.module}:CAPTIONS")

    @property
    def aircut(self) -> Callable[[dict], dict | None] | None:
        return resolve(f"{self.module}:{self.aircut_summary}") if self.aircut_summary else None


@dataclass(frozen=True)
class ProgressCount:
    """What a machinist counts while the job runs: the event marking one more item."""

    event: str  # the job_events name counted
    unit: str  # what one of them is called: hole, pass
    total: Callable[[Job], int]


@dataclass(frozen=True)
class JobKind:
    """One machining method: how its jobs are planned, segmented, judged, drawn and counted."""

    name: str
    plan: Callable[[Job, Machine, PlanBuilder, Kinematics], None]
    layouts: tuple[str, ...] | None = None  # machine layouts that can run it (None: every layout)
    segmenting: Segmenting | None = None
    report: ReportSection | None = None
    figures: Figures | None = None
    progress: ProgressCount | None = None
    # In a program, what must hold before its operation begins: the drill's timing search
    # starts from drives at rest, so it waits for the operation before to settle
    settle_before: Callable[[Job, Machine, PlanBuilder, Kinematics], None] | None = None

