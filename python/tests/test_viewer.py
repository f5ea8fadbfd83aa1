"""`sage3d view`: the viewer's HTTP API against the command line's own outputs, `sage3d.view`
from Python, and the page in a real headless Chromium (selenium): the map shows the scene's
objects, keys drive the agent, the player scrubs a run, and an episode played to STOP is
recorded exactly as `sage3d eval --agent replay:FILE` scores the same actions."""

import io
import json
import os
import pathlib
import shutil
import signal
import subprocess
import sys
import time
import urllib.error
import urllib.request

import numpy as np
import pytest
from PIL import Image

from conftest import few_vln_split

REPO = pathlib.Path(__file__).resolve().parents[2]
BINARY = os.environ.get("SAGE3D_BIN", str(REPO / "target" / "debug" / "sage3d"))
SHOTS = os.environ.get("SAGE3D_SCREENSHOTS")
"""Where the browser tests save their screenshots, when set."""


@pytest.fixture(scope="module")
def world(tmp_path_factory, sage3d):
    """A synthetic home, its dataset with a `few` split of three VLN episodes, and the oracle's
    evaluation of that split: (scenes, data, run, instructions)."""
    root = tmp_path_factory.mktemp("viewer")
    scenes, data, instructions = few_vln_split(sage3d, root)
    run = root / "oracle"
    sage3d("eval", data, "--scenes", scenes, "--split", "few", "--agent", "oracle", "--out", run)
    return scenes, data, run, instructions


class Viewer:
    """`sage3d view …` on a free port, stopped on exit."""

    def __init__(self, *args):
        self.proc = subprocess.Popen(
            [BINARY, "view", *map(str, args), "--port", "0"],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        line = self.proc.stdout.readline()
        if "open http" not in line:
            self.proc.kill()
            raise AssertionError(f"sage3d view did not start: {line}{self.proc.stderr.read()}")
        self.url = line.split("open ", 1)[1].strip()
        self.base = self.url.split("?")[0].rstrip("/")

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.proc.send_signal(signal.SIGINT)
        try:
            self.proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            self.proc.kill()

    def get(self, path):
        with urllib.request.urlopen(self.base + path, timeout=120) as r:
            return r.read(), dict(r.headers)

    def json(self, path, body=None):
        data = None if body is None else json.dumps(body).encode()
        req = urllib.request.Request(self.base + path, data=data, headers={"content-type": "application/json"})
        with urllib.request.urlopen(req, timeout=120) as r:
            return json.loads(r.read())


def test_frame_is_what_sage3d_render_gives_at_that_pose(world, sage3d, tmp_path):
    scenes, _, run, _ = world
    with Viewer(run) as v:
        info = v.json("/api/info")
        assert info["kind"] == "run" and len(info["episodes"]) == 3
        ep = v.json("/api/episodes/" + info["episodes"][0]["id"])
        assert ep["steps"], "the oracle walked"
        step = ep["steps"][len(ep["steps"]) // 2]
        query = f"x={step['x']}&y={step['y']}&z={step['z']}&yaw={step['yaw']}&width=160&height=120&format=png"
        png, headers = v.get(f"/api/scenes/{ep['scene']}/frame?{query}")
        command = headers["x-sage3d-render"].split()
    assert command[:2] == ["sage3d", "render"]
    out = tmp_path / "render"
    command[command.index("--out") + 1] = str(out)
    sage3d(*command[1:])
    viewer = np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), dtype=np.int16)
    cli = np.asarray(Image.open(out / "rgb.png").convert("RGB"), dtype=np.int16)
    assert viewer.shape == cli.shape == (120, 160, 3)
    # The command carries the heading in degrees: at most a rounding of the last float bit.
    assert np.abs(viewer - cli).max() <= 2
    assert viewer.std() > 5, "a real image, not a blank"


def test_episode_records_are_served_as_the_run_holds_them(world):
    _, _, run, instructions = world
    records = {
        r["episode_id"]: r for r in map(json.loads, (run / "episodes.jsonl").read_text().splitlines())
    }
    with Viewer(run) as v:
        for eid, rec in records.items():
            ep = v.json(f"/api/episodes/{eid}")
            assert ep["instruction"] == instructions[eid]
            # The server reads the records back with serde_json's default float parser, which may
            # land one ulp from the written number.
            assert ep["sr"] == rec["metrics"]["sr"] and ep["ne"] == pytest.approx(rec["metrics"]["ne"], rel=1e-12)
            steps = rec["record"]["steps"]
            assert [[s["x"], s["y"]] for s in ep["steps"]] == [s["position"][:2] for s in steps]
            assert ep["steps"][-1]["action"] == "stop"
        # The player's export: the episode as an animation, a frame for the start and each step.
        eid, rec = next(iter(records.items()))
        gif, headers = v.get(f"/api/episodes/{eid}/video.gif")
        assert headers["content-type"] == "image/gif" and "attachment" in headers["content-disposition"]
        animation = Image.open(io.BytesIO(gif))
        assert animation.n_frames == len(rec["record"]["steps"]) + 1
        with pytest.raises(urllib.error.HTTPError) as e:
            v.get("/api/episodes/..%2Fsummary.json")
        assert e.value.code == 404


def test_python_view_serves_until_interrupted(world):
    scenes = world[0]
    # The child takes SIGINT as Python's KeyboardInterrupt whatever the test runner inherited
    # (a job started in the background by a non-interactive shell ignores SIGINT, and so would
    # the child).
    script = (
        "import signal, sys, sage3d\n"
        "signal.signal(signal.SIGINT, signal.default_int_handler)\n"
        f"sage3d.view({str(scenes)!r}, port=0, on_ready=lambda url: print(url, flush=True))\n"
    )
    proc = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        url = proc.stdout.readline().strip()
        assert url.startswith("http://127.0.0.1:"), proc.stderr.read()
        with urllib.request.urlopen(url.rstrip("/") + "/api/info", timeout=60) as r:
            assert json.loads(r.read())["scenes"] == ["home1"]
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=20)
    finally:
        proc.kill()
    assert proc.returncode != 0 and "KeyboardInterrupt" in err


def test_an_exception_in_on_ready_stops_the_viewer_and_is_raised(world):
    import sage3d

    def fail(url):
        raise RuntimeError(f"no browser for {url}")

    with pytest.raises(RuntimeError, match="no browser for http://127.0.0.1:"):
        sage3d.view(str(world[0]), port=0, on_ready=fail)


# ---------- in a real browser ----------


def chromium_driver():
    """Headless Chromium through chromedriver (Debian's `chromium` and `chromium-driver`), the
    window 1400 px wide; a skip (or a failure under SAGE3D_REQUIRE_BROWSER=1) without them."""
    browser = shutil.which("chromium") or shutil.which("chromium-browser")
    driver = shutil.which("chromedriver")
    try:
        from selenium import webdriver
        from selenium.webdriver.chrome.service import Service
    except ImportError:
        browser = None
    if not (browser and driver):
        message = "headless Chromium with chromedriver and selenium are needed for the browser tests"
        if os.environ.get("SAGE3D_REQUIRE_BROWSER") == "1":
            pytest.fail(message)
        pytest.skip(message)
    opts = webdriver.ChromeOptions()
    opts.binary_location = browser
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage", "--window-size=1400,1000"):
        opts.add_argument(arg)
    return webdriver.Chrome(service=Service(executable_path=driver), options=opts)


@pytest.fixture
def browser():
    d = chromium_driver()
    d.set_script_timeout(120)
    yield d
    d.quit()


def wait(driver, condition, what, timeout=120):
    """Polls `condition()` until it is true; fails naming `what` (the page's message too)."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        value = condition()
        if value:
            return value
        time.sleep(0.1)
    message = driver.execute_script("return document.getElementById('message').textContent")
    raise AssertionError(f"timed out waiting for {what}; the page says: {message!r}")


def state(driver, expr):
    return driver.execute_script(f"return {expr}")


def shot(driver, name):
    if SHOTS:
        pathlib.Path(SHOTS).mkdir(parents=True, exist_ok=True)
        driver.save_screenshot(str(pathlib.Path(SHOTS) / f"{name}.png"))


def frame_pixels(driver):
    return driver.find_element("id", "fpv").screenshot_as_png


def test_browser_map_objects_and_keyboard_driving(world, browser):
    from selenium.webdriver.common.action_chains import ActionChains

    scenes = world[0]
    with Viewer(scenes) as v:
        browser.get(v.url)
        wait(browser, lambda: state(browser, "document.body.dataset.ready === '1'"), "the page")
        wait(browser, lambda: state(browser, "viewer.frames") >= 1, "the first frame")
        # The map lists the scene's objects, and hovering one names it.
        map_data = json.loads(v.get("/api/scenes/home1/map")[0])
        items = state(browser, "viewer.map.items.map(i => i.id)")
        assert items == [i["id"] for i in map_data["items"]] and items
        canvas = browser.find_element("id", "map")
        target = next(i for i in map_data["items"] if "state" not in i or i["state"] is None)
        xs, ys = zip(*target["polygon"])
        u, v_ = state(browser, f"toCanvas({sum(xs) / len(xs)}, {sum(ys) / len(ys)})")
        w, h = canvas.size["width"], canvas.size["height"]
        ActionChains(browser).move_to_element_with_offset(canvas, int(u - w / 2), int(v_ - h / 2)).perform()
        tip = wait(browser, lambda: browser.find_element("id", "tip").text, "the hover label")
        assert target["id"] in tip, tip
        # Keys step the agent through the environment: the pose and the image change.
        before = state(browser, "viewer.state")
        pixels = frame_pixels(browser)
        frames = state(browser, "viewer.frames")
        browser.find_element("tag name", "body").send_keys("a")
        wait(browser, lambda: state(browser, "viewer.state.step") == 1, "a turn")
        wait(browser, lambda: state(browser, "viewer.frames") > frames, "the new frame")
        after = state(browser, "viewer.state")
        assert abs(after["pose"]["yaw"] - before["pose"]["yaw"]) > 0.2
        assert frame_pixels(browser) != pixels
        browser.find_element("tag name", "body").send_keys("w")
        wait(browser, lambda: state(browser, "viewer.state.step") == 2, "a step forward")
        moved = state(browser, "viewer.state.pose")
        assert (moved["x"], moved["y"]) != (after["pose"]["x"], after["pose"]["y"]) or state(browser, "viewer.state.contact")
        # The depth switch renders the depth image.
        browser.find_element("css selector", "input[value=depth]").click()
        wait(browser, lambda: "layer=depth" in (state(browser, "document.getElementById('fpv').dataset.src") or ""), "depth")
        shot(browser, "explore")


def test_browser_player_scrubs_a_run(world, browser):
    run = world[2]
    with Viewer(run) as v:
        browser.get(v.url)
        wait(browser, lambda: state(browser, "document.body.dataset.ready === '1'"), "the page")
        first = state(browser, "viewer.info.episodes[0].id")
        assert state(browser, "viewer.mode") == "player" and state(browser, "viewer.episode.id") == first
        wait(browser, lambda: state(browser, "viewer.frames") >= 1, "the first frame")
        n = state(browser, "viewer.episode.steps.length")
        pixels = frame_pixels(browser)
        # Scrub with the timeline to the middle, then step with ].
        browser.execute_script(
            "const t = document.getElementById('timeline'); t.value = arguments[0]; t.dispatchEvent(new Event('input'));",
            n // 2,
        )
        assert state(browser, "viewer.index") == n // 2
        frames = state(browser, "viewer.frames")
        browser.find_element("tag name", "body").send_keys("]")
        assert state(browser, "viewer.index") == n // 2 + 1
        wait(browser, lambda: state(browser, "viewer.frames") > frames, "the scrubbed frame")
        assert frame_pixels(browser) != pixels
        status = browser.find_element("id", "status").text
        assert f"step {n // 2 + 1}/{n}" in status and "action" in status
        # The list is searchable.
        other = state(browser, "viewer.info.episodes[1].id")
        browser.find_element("id", "search").send_keys(other)
        shown = [li.get_attribute("data-id") for li in browser.find_elements("css selector", "#episodes li")]
        assert shown == [other]
        shot(browser, "player")


def test_browser_human_play_is_scored_as_eval_scores_its_actions(world, browser, sage3d, tmp_path):
    scenes, data, _, _ = world
    human = tmp_path / "human"
    keys = ["w", "w", "a", "w", "d", "w"]
    with Viewer(data, "--scenes", scenes, "--split", "few", "--play", human) as v:
        browser.get(v.url)
        wait(browser, lambda: state(browser, "document.body.dataset.ready === '1'"), "the page")
        assert state(browser, "viewer.mode") == "play" and not state(browser, "viewer.mapVisible")
        first = browser.find_elements("css selector", "#episodes li")[0]
        eid = first.get_attribute("data-id")
        first.click()
        wait(browser, lambda: state(browser, "viewer.session") and state(browser, "viewer.state.episode") == eid, "the episode")
        size = state(browser, "viewer.info.play.size")
        wait(browser, lambda: state(browser, "viewer.frames") >= 1, "the first frame")
        assert state(browser, "document.getElementById('fpv').naturalWidth") == size[0]
        body = browser.find_element("tag name", "body")
        for k, key in enumerate(keys, start=1):
            body.send_keys(key)
            wait(browser, lambda: state(browser, "viewer.state.step") == k, f"step {k}")
        body.send_keys("s")
        assert not state(browser, "viewer.state.done"), "one S only arms STOP"
        body.send_keys("s")
        wait(browser, lambda: state(browser, "viewer.state.done"), "STOP")
        wait(browser, lambda: state(browser, "viewer.info.play.played") == 1, "the record")
        shot(browser, "human-play")
    records = [json.loads(line) for line in (human / "episodes.jsonl").read_text().splitlines()]
    assert [r["episode_id"] for r in records] == [eid] and records[0]["agent"] == "human"
    assert records[0].get("notes", []) == [], "the map stayed hidden"
    names = {"w": "MOVE_FORWARD", "a": "TURN_LEFT", "d": "TURN_RIGHT"}
    replay = tmp_path / "replay.jsonl"
    replay.write_text(json.dumps({"episode_id": eid, "actions": [names[k] for k in keys] + ["STOP"]}) + "\n")
    sage3d("eval", data, "--scenes", scenes, "--split", "few", "--agent", f"replay:{replay}", "--out", tmp_path / "replayed")
    replayed = {
        r["episode_id"]: r
        for r in map(json.loads, (tmp_path / "replayed" / "episodes.jsonl").read_text().splitlines())
    }[eid]
    for field in ("metrics", "record", "termination"):
        assert records[0][field] == replayed[field], field
    # The human run is a run folder: the report reads it.
    sage3d("report", human)
    assert (human / "report.html").is_file()
