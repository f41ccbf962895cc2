"""The planner's 3D page: the figure it is built from, and the page itself in a real Chromium.

The browser tests open ``plan.html`` from disk in headless Chromium (the Debian package), take a
screenshot and Chromium's own network log. They check that plotly finished drawing, that the
3D canvas holds the figure's colours, and that the page asked for nothing but local files. The
checks are shown to fail on a page without plotly.js and on one that loads plotly.js from a CDN.
Outside CI they skip when Chromium is missing; in CI it is installed (scripts/apt_ensure.sh).
Page size and render time are logged (``-o log_cli=true --log-cli-level=INFO`` shows them),
never asserted as times.
"""

from __future__ import annotations

import json
import logging
import re
import shutil
import subprocess
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from needs import in_ci
from PIL import Image
from scipy.spatial import ConvexHull

from nbv.geometry.camera import look_at
from nbv.plan.page import (
    BACKGROUND_COLOUR,
    CANDIDATE_COLOUR,
    CHOSEN_COLOUR,
    MAX_PAGE_POINTS,
    POINT_COLOUR,
    build_plan_figure,
    frustum_segments,
    subsample_evenly,
    write_plan_page,
)

log = logging.getLogger(__name__)
ROOT = Path(__file__).resolve().parents[1]
WINDOW = (1000, 800)
#: Flags that keep headless Chromium from calling Google's services on its own (updates,
#: sign-in, network time); the resolver rule makes every host name unknown, so nothing at all can
#: leave the machine even if something asks. file:// loads do not go through the resolver.
CHROMIUM_FLAGS = [
    "--headless", "--no-sandbox", "--disable-gpu", "--enable-unsafe-swiftshader",
    "--disable-quic", "--no-first-run", "--disable-background-networking",
    "--disable-component-update", "--disable-sync", "--disable-default-apps",
    "--disable-domain-reliability", "--no-pings", "--host-resolver-rules=MAP * ~NOTFOUND",
    f"--window-size={WINDOW[0]},{WINDOW[1]}",
]  # fmt: skip
#: URL schemes a self-contained page may use.
LOCAL_SCHEMES = ("file:", "data:", "blob:", "about:", "chrome:")


# ---------------------------------------------------------------------------------------------
# The figure, without a browser


def scene(n_points: int = 50_000, n_views: int = 33):
    """A flattened Gaussian blob, its hull and cameras on a sphere of radius 1.5 looking at it."""
    rng = np.random.default_rng(0)
    points = (rng.normal(size=(n_points, 3)) * [0.3, 0.2, 0.1]).astype(np.float32)
    hull = ConvexHull(points)
    eyes = rng.normal(size=(n_views, 3))
    eyes *= 1.5 / np.linalg.norm(eyes, axis=1, keepdims=True)
    return dict(
        points=points,
        hull_vertices=points[hull.vertices],
        hull_faces=np.searchsorted(hull.vertices, hull.simplices),
        candidates=np.stack([look_at(e) for e in eyes]),
    )


def test_subsample_keeps_evenly_spaced_rows_and_small_clouds_whole():
    points = np.arange(30, dtype=np.float32).reshape(10, 3)
    assert subsample_evenly(points, 10) is points
    np.testing.assert_array_equal(subsample_evenly(points, 4), points[[0, 3, 6, 9]])


def test_frustums_open_along_each_cameras_plus_z_from_its_centre():
    poses = scene(n_points=100, n_views=5)["candidates"]
    lines = frustum_segments(poses, depth=0.2).reshape(5, 12, 3)
    assert np.isnan(lines[:, 11]).all() and np.isfinite(lines[:, :11]).all()
    corners, apex = lines[:, :4], lines[:, [6, 9]]
    np.testing.assert_allclose(lines[:, 4], corners[:, 0])  # the rectangle is closed
    np.testing.assert_allclose(apex, np.repeat(poses[:, None, :3, 3], 2, axis=1))
    # The far rectangle's centre lies `depth` along the optical axis (+z, the pose's 3rd column).
    np.testing.assert_allclose(
        corners.mean(axis=1) - poses[:, :3, 3], 0.2 * poses[:, :3, 2], atol=1e-12
    )


def test_figure_draws_every_part_with_the_chosen_views_numbered_in_order():
    s = scene()
    fig = build_plan_figure(**s, chosen=[7, 2, 30], visited=[0, 7], title="box")
    names = [t.name for t in fig.data]
    assert names == ["cloud", "hull", "candidates", "candidates", "visited", "visited", "chosen",
                     "chosen", "order"]  # fmt: skip
    cloud, hull = fig.data[0], fig.data[1]
    np.testing.assert_array_equal(cloud.x, subsample_evenly(s["points"], MAX_PAGE_POINTS)[:, 0])
    assert len(cloud.x) == MAX_PAGE_POINTS
    np.testing.assert_array_equal(hull.i, s["hull_faces"][:, 0])
    hover = {fig.data[k].name: list(fig.data[k].hovertext) for k in (3, 5, 7)}
    # View 7 is both visited and chosen: drawn as chosen.
    assert hover["visited"] == ["view 0"]
    assert hover["chosen"] == ["view 2", "view 7", "view 30"]
    assert hover["candidates"] == [f"view {v}" for v in range(33) if v not in (0, 2, 7, 30)]
    order = fig.data[8]
    assert list(order.text) == ["1", "2", "3"]
    np.testing.assert_array_equal(order.x, s["candidates"][[7, 2, 30], 0, 3])
    assert fig.layout.scene.camera.up.to_plotly_json() == {"x": 0, "y": 1, "z": 0}
    assert fig.layout.title.text == "box"
    down = build_plan_figure(**s, chosen=[7], visited=[], title="z", up="-z")
    assert down.layout.scene.camera.up.to_plotly_json() == {"x": 0, "y": 0, "z": -1}


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (dict(points=np.zeros((4, 2))), "points: shape (4, 2) is not (N, 3)"),
        (dict(points=np.full((4, 3), np.nan)), "points: holds NaN"),
        (dict(candidates=np.zeros((0, 4, 4))), "candidates: no camera poses"),
        (dict(candidates=np.zeros((3, 3, 4))), "candidates: shape (3, 3, 4) is not (N, 4, 4)"),
        (dict(hull_faces=np.array([[0, 1, 99]])), "hull_faces: vertex index 99"),
        (dict(hull_faces=np.zeros((1, 3))), "hull_faces: dtype float64 is not an integer"),
        (dict(chosen=[1, 33]), "chosen: view index 33 is out of range; allowed 0..32"),
        (dict(chosen=[1, 1]), "chosen: repeats a view"),
        (dict(visited=[-1]), "visited: view index -1 is out of range"),
        (dict(up="w"), "up: 'w' is not one of ['-x', '-y', '-z', 'x', 'y', 'z']"),
    ],
)
def test_bad_input_is_refused_by_name_and_nothing_is_written(tmp_path, change, message):
    args = dict(scene(n_points=200), chosen=[1], visited=[], title="t") | change
    path = tmp_path / "plan.html"
    with pytest.raises(ValueError) as err:
        write_plan_page(path, **args)
    assert message in str(err.value)
    assert list(tmp_path.iterdir()) == []


def test_page_is_self_contained_and_under_10_mb(tmp_path):
    path = tmp_path / "plan.html"
    write_plan_page(path, **scene(), chosen=[3, 7, 1], visited=[0, 3], title="blob")
    html = path.read_text()
    assert not re.search(r"<script[^>]*\bsrc=", html)  # plotly.js is inline, nothing fetched
    assert "plotly.js v" in html
    assert path.stat().st_size < 10_000_000
    assert list(tmp_path.iterdir()) == [path]  # no temporary file left


# ---------------------------------------------------------------------------------------------
# The page in a real browser


@pytest.fixture(scope="session")
def chromium() -> str:
    """The Chromium binary; installed in CI when missing, else the tests skip."""
    binary = shutil.which("chromium")
    if binary is None and not in_ci():
        pytest.skip("Chromium is missing; bash scripts/apt_ensure.sh tests chromium (as root)")
    if binary is None:
        install = subprocess.run(
            ["bash", str(ROOT / "scripts" / "apt_ensure.sh"), "test_plan_page", "chromium"],
            capture_output=True, text=True, timeout=900,
        )  # fmt: skip
        binary = shutil.which("chromium")
        if install.returncode != 0 or binary is None:
            pytest.fail(f"could not install Chromium:\n{install.stderr}", pytrace=False)
    return binary


@dataclass
class BrowserRun:
    """What headless Chromium saw of a page.

    Attributes:
        image: (H, W, 3) uint8 screenshot of the window.
        ready_ms: when plotly finished drawing (ms after navigation start), None if it never did.
        page_requests: URLs the page asked for over the network stack (not file://).
        browser_requests: URLs Chromium itself asked for (``initiator: not an origin``).
        seconds: wall time of the whole Chromium run (start-up, load, draw, screenshot).
    """

    image: np.ndarray
    ready_ms: int | None
    page_requests: list[str]
    browser_requests: list[str]
    seconds: float


def open_in_chromium(binary: str, page: Path, work: Path) -> BrowserRun:
    """Open ``page`` from disk in a fresh headless Chromium profile; screenshot, DOM, net log."""
    work.mkdir(parents=True, exist_ok=True)
    shot, net = work / "shot.png", work / "net.json"
    t0 = time.perf_counter()
    proc = subprocess.run(
        [binary, *CHROMIUM_FLAGS, f"--user-data-dir={work / 'profile'}", f"--screenshot={shot}",
         f"--log-net-log={net}", "--dump-dom", page.resolve().as_uri()],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    seconds = time.perf_counter() - t0
    if proc.returncode != 0 or not shot.exists():
        pytest.fail(f"chromium exited with {proc.returncode}:\n{proc.stderr[-3000:]}")
    ready = re.search(r'<html[^>]*data-plot-ready-ms="(\d+)"', proc.stdout)
    log_data = json.loads(net.read_text())
    names = {v: k for k, v in log_data["constants"]["logEventTypes"].items()}
    page_requests, browser_requests = [], []
    for event in log_data["events"]:
        params = event.get("params", {})
        if names[event["type"]] == "URL_REQUEST_START_JOB" and "url" in params:
            if params["url"].startswith(LOCAL_SCHEMES):
                continue
            own = params.get("initiator") == "not an origin"
            (browser_requests if own else page_requests).append(params["url"])
    image = np.asarray(Image.open(shot).convert("RGB"))
    return BrowserRun(
        image, int(ready.group(1)) if ready else None, page_requests, browser_requests, seconds
    )


def _rgb(colour: str) -> np.ndarray:
    return np.array([int(colour[i : i + 2], 16) for i in (1, 3, 5)])


def colour_pixels(image: np.ndarray, colour: str, tolerance: int = 40) -> int:
    """Pixels of the 3D scene's region within ``tolerance`` (max channel difference) of
    ``colour``. The region leaves out the title bar and the legend on the right, which plotly
    draws as SVG even when WebGL or the scene fails."""
    h, w, _ = image.shape
    region = image[int(0.1 * h) : int(0.95 * h), int(0.02 * w) : int(0.8 * w)].astype(int)
    return int((np.abs(region - _rgb(colour)).max(axis=-1) <= tolerance).sum())


def canvas_drawn(run: BrowserRun) -> bool:
    """plotly finished, and the scene region shows the cloud, the chosen and the candidate
    cameras' colours over a background that is not all there is."""
    counts = [colour_pixels(run.image, c) for c in (POINT_COLOUR, CHOSEN_COLOUR, CANDIDATE_COLOUR)]
    background = colour_pixels(run.image, BACKGROUND_COLOUR, tolerance=0)
    h, w, _ = run.image.shape
    log.info("scene pixels: cloud, chosen, candidates %s; background %d", counts, background)
    return run.ready_ms is not None and min(counts) >= 50 and background < 0.9 * h * w


@pytest.mark.slow
def test_page_renders_in_chromium_from_disk_without_the_network(chromium, tmp_path):
    page = tmp_path / "plan.html"
    write_plan_page(page, **scene(), chosen=[3, 7, 1], visited=[0, 3], title="blob")
    run = open_in_chromium(chromium, page, tmp_path / "chromium")
    log.info(
        "plan.html: %.2f MB; drawn %s ms after navigation start; whole Chromium run %.2f s; "
        "Chromium's own requests (blocked): %s",
        page.stat().st_size / 1e6, run.ready_ms, run.seconds, run.browser_requests,
    )  # fmt: skip
    assert run.page_requests == []
    assert run.image.shape[:2] == (WINDOW[1], WINDOW[0])
    assert canvas_drawn(run)


def test_the_checks_fail_on_a_page_without_plotly_js(chromium, tmp_path):
    page = tmp_path / "broken.html"
    figure = build_plan_figure(**scene(2000), chosen=[3, 7], visited=[0], title="no plotly")
    page.write_text(figure.to_html(include_plotlyjs=False))
    run = open_in_chromium(chromium, page, tmp_path / "chromium")
    assert run.ready_ms is None
    assert not canvas_drawn(run)
    assert colour_pixels(run.image, POINT_COLOUR) == 0


def test_the_checks_catch_a_page_that_loads_plotly_js_from_the_network(chromium, tmp_path):
    page = tmp_path / "cdn.html"
    figure = build_plan_figure(**scene(2000), chosen=[3, 7], visited=[0], title="cdn")
    page.write_text(figure.to_html(include_plotlyjs="cdn"))
    run = open_in_chromium(chromium, page, tmp_path / "chromium")
    assert len(run.page_requests) == 1 and run.page_requests[0].startswith("https://cdn.plot.ly/")
    assert not canvas_drawn(run)
