"""cnc-run's report page: one self-contained HTML file that a browser renders with every plot.

The page is rendered by headless Chromium (Debian's `chromium`, installed by `make setup`)
from the file system with the network off; the screenshot must show a real page, and the
plots must be what makes it: the same page with the images' data broken looks different.
"""
from __future__ import annotations

import base64
import io
import re
import shutil
import subprocess
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest
from matplotlib.image import imread

from support import JOBS, cnc, load_report

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
WINDOW = (1280, 2000)


class Page(HTMLParser):
    """The <img> sources and every URL-bearing attribute of a page."""

    def __init__(self) -> None:
        super().__init__()
        self.images: list[str] = []
        self.links: list[str] = []
        self.scripts = 0

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        if tag == "img":
            self.images.append(attrs.get("src") or "")
        if tag == "script":
            self.scripts += 1
        self.links += [v for k, v in attrs.items() if k in ("href", "src") and v]


def screenshot(page: Path, out: Path, tmp: Path) -> np.ndarray:
    chromium = shutil.which("chromium")
    if chromium is None:
        pytest.fail("chromium is not installed: run `make setup` (installs Debian's chromium package)")
    cmd = [chromium, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
           "--disable-background-networking", "--disable-component-update", "--disable-sync",
           f"--user-data-dir={tmp / 'chromium-profile'}", f"--screenshot={out}",
           f"--window-size={WINDOW[0]},{WINDOW[1]}", page.resolve().as_uri()]
    result = subprocess.run(cmd, capture_output=True, text=True, timeout=90)
    assert result.returncode == 0 and out.exists(), result.stderr[-2000:]
    return imread(out)[:, :, :3]


def test_cnc_run_writes_a_self_contained_report_page_that_renders(tmp_path):
    out = tmp_path / "drill"
    result = cnc("cnc-run", JOBS / "drill_row.yaml", "--out", out)
    assert result.returncode == 0, result.stderr[-3000:]
    report = load_report(out)
    page = out / "report.html"
    assert page.exists() and f"report {page}" in result.stdout

    # Self-contained: no script, no reference to anything but data: URIs.
    text = page.read_text()
    parsed = Page()
    parsed.feed(text)
    assert parsed.scripts == 0
    assert all(link.startswith("data:") for link in parsed.links), [link[:60] for link in parsed.links]
    assert not re.search(r"url\(|@import|https?://", text)

    # Every plot in DIR/plots is on the page, and every image is a PNG that decodes.
    plots = sorted((out / "plots").glob("*.png"))
    assert {p.stem for p in plots} >= {"drill_xz", "drill_timing", "following_error"}
    assert len(parsed.images) == len(plots)
    embedded = set()
    for src in parsed.images:
        assert src.startswith("data:image/png;base64,")
        data = base64.b64decode(src.split(",", 1)[1], validate=True)
        assert data.startswith(PNG_SIGNATURE)
        pixels = imread(io.BytesIO(data))
        assert pixels.shape[0] > 100 and pixels.shape[1] > 100 and pixels.std() > 0
        embedded.add(data)
    assert embedded == {p.read_bytes() for p in plots}

    # The verdicts a machinist looks for first.
    assert report["drill"]["safety_violations"] == 0
    for words in ("SUCCEEDED", "Safety", "safe", "faster than conventional", "lower bound",
                  "Following error", "chunks lost", "Holes"):
        assert words in text, words

    # Chromium renders it: not blank, and the plots are a large part of what is seen.
    shot = screenshot(page, tmp_path / "page.png", tmp_path)
    assert shot.shape[:2] == (WINDOW[1], WINDOW[0])
    assert shot.std() > 0.05
    non_white = (shot < 0.9).any(axis=2)
    assert non_white.mean() > 0.10
    broken = tmp_path / "broken.html"
    broken.write_text(re.sub(r"data:image/png;base64,[A-Za-z0-9+/=]+", "data:image/png;base64,AAAA", text))
    without = screenshot(broken, tmp_path / "broken.png", tmp_path)
    changed = (np.abs(shot - without) > 0.1).any(axis=2)
    assert changed.mean() > 0.06, f"the plots change only {changed.mean():.1%} of the screenshot"
    shutil.copy(tmp_path / "page.png", out / "screenshot.png")  # kept for a look under pytest's tmp dir


def test_cnc_run_progress_in_a_log_is_sparse_and_counts_holes(tmp_path):
    result = cnc("cnc-run", JOBS / "drill_row.yaml", "--out", tmp_path / "drill")
    assert result.returncode == 0, result.stderr[-3000:]
    lines = result.stdout.splitlines()
    running = [line for line in lines if "%" in line and "sim " in line]
    assert 3 <= len(running) <= 11, result.stdout  # at most one per 10 % (a 4 s job, well under 5 s)
    assert "\r" not in result.stdout  # not a terminal: plain lines
    assert any(re.search(r"hole [1-5]/5", line) for line in running), running
    assert any(line.strip() == "drill-row-demo: accepted" for line in lines)
    assert any(line.startswith("job drill-row-demo: succeeded") for line in lines)  # the summary
