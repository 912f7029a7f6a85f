"""``muble site``: the results website built from real ``muble eval`` runs (the oracle with keyframes, random, and
the LLM agent against a scripted server), checked file by file and in headless Chromium: the leaderboard sorts and
filters, a run leads to its episodes, an episode shows its keyframes, decisions and, for the LLM, its dialogue, no
link is broken and the console logs no error. A 1,000-episode run's pages load at once."""
from __future__ import annotations

import functools
import http.server
import json
import os
import re
import shutil
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from tests.app.test_app_protocol import muble
from tests.llm.chat_server import Reply, ScriptedChatServer

pytestmark = pytest.mark.slow

CHROMIUM, DRIVER = shutil.which("chromium"), shutil.which("chromedriver")
SHOTS = "MUBLE_SITE_SCREENSHOTS"  # a folder for the browser test's screenshots (docs/images for the docs)
SMALL_FRAMES = ["evaluation.render=true", "evaluation.keyframes=true", "renderer.width=160", "renderer.height=120",
                "renderer.shadows=false"]


@pytest.fixture(scope="module")
def runs(tmp_path_factory) -> dict[str, Path]:
    """Three runs on the first episodes of shopvrb2_v2's shipped mini split."""
    base = tmp_path_factory.mktemp("site_runs")
    env = {"MUBLE_DATA_CACHE": str(base / "cache")}
    out = {}
    for name, args in (("oracle", ["agent=oracle", "evaluation.limit=2", *SMALL_FRAMES]),
                       ("random", ["agent=random", "evaluation.limit=2"])):
        out[name] = base / name
        done = muble("eval", "protocol=shopvrb2_v2", *args, "dataset.workers=1", f"hydra.run.dir={out[name]}",
                     cwd=base, env=env)
        assert done.returncode == 0, done.stderr[-3000:]
    with ScriptedChatServer() as server:  # a reply that is no decision, asked again, then a decision
        server.play(Reply("I would pick up the glass first."), Reply(json.dumps({"name": "lift", "params": {}})),
                    Reply(json.dumps({"answer": "done"})))
        out["llm"] = base / "llm"
        done = muble("eval", "protocol=shopvrb2_v2", "agent=llm", f"agent.base_url={server.base_url}",
                     "agent.timeout=30", "evaluation.limit=1", "dataset.workers=1", f"hydra.run.dir={out['llm']}",
                     cwd=base, env=env)
        assert done.returncode == 0, done.stderr[-3000:]
    return out


@pytest.fixture(scope="module")
def site(runs, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("site") / "site"
    done = muble("site", *(str(p) for p in runs.values()), f"--out={out}", cwd=out.parent)
    assert done.returncode == 0, done.stderr[-3000:]
    assert "5 episode pages" in done.stdout, done.stdout
    return out


def _links(page: Path) -> list[str]:
    return re.findall(r'(?:href|src)="([^"#]+)"', page.read_text(encoding="utf-8"))


def test_every_page_and_link_of_the_site_exists(site):
    pages = sorted(site.rglob("*.html"))
    assert (site / "index.html") in pages and len(pages) == 1 + 3 + 5  # leaderboard, a page per run, episodes
    broken = [(str(p.relative_to(site)), link) for p in pages for link in _links(p)
              if not link.startswith(("http:", "https:", "data:")) and not (p.parent / link).exists()]
    assert broken == []


def test_an_episode_page_shows_keyframes_decisions_truth_and_the_other_runs(site, runs):
    page = (site / "runs" / "oracle" / "mini" / "000000.html").read_text()
    record = json.loads((runs["oracle"] / "episodes_mini.jsonl").read_text().splitlines()[0])
    assert record["instruction"] in page and record["outcome"] == "success"
    frames = re.findall(r'<img src="(SHOP_VRB2_mini_000000/\d{4}\.png)"', page)
    assert len(frames) == len(record["keyframes"]) == len(record["steps"]) + 1 > 2
    assert "episode.gif" in page
    for step in record["steps"]:
        assert f"<code>{step['action']}</code>".replace("'", "&#39;") in page
    assert '../../../runs/random/mini/000000.html' in page  # the same episode under another run
    # An episode that weighs sets the measurement beside the scene file's weight.
    weighing = [(r["index"], s) for line in (runs["oracle"] / "episodes_mini.jsonl").read_text().splitlines()
                for r in [json.loads(line)] for s in r["steps"] if s["action"].startswith("weigh(")]
    for index, _step in weighing:
        episode = (site / "runs" / "oracle" / "mini" / f"{index:06d}.html").read_text()
        assert "Measured against true values" in episode


def test_the_llm_episode_shows_its_dialogue(site):
    page = (site / "runs" / "llm" / "mini" / "000000.html").read_text()
    assert "Dialogue" in page and "I would pick up the glass first." in page and "unusable reply" in page
    assert "request" in page and "system" in page


def test_bad_input_writes_nothing(tmp_path, runs):
    out = tmp_path / "site"
    done = muble("site", str(runs["oracle"]), str(tmp_path / "missing"), f"--out={out}", cwd=tmp_path)
    assert done.returncode == 2 and "does not exist" in done.stderr and not out.exists()
    done = muble("site", str(runs["oracle"]), f"--out={runs['oracle']}", cwd=tmp_path)
    assert done.returncode == 2 and "is one of the runs" in done.stderr


# --- in the browser ----------------------------------------------------------------------------------------------
class Quiet(http.server.SimpleHTTPRequestHandler):
    def log_message(self, *args) -> None:
        pass


@pytest.fixture(scope="module")
def served(site):
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), functools.partial(Quiet, directory=str(site.parent)))
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    yield f"http://127.0.0.1:{server.server_address[1]}/{site.name}"
    server.shutdown()


@pytest.fixture(scope="module")
def browser():
    if not (CHROMIUM and DRIVER):
        pytest.skip("needs Debian's chromium and chromium-driver (scripts/setup.sh installs them)")
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                "--window-size=1280,1600"):
        options.add_argument(arg)
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    driver = webdriver.Chrome(service=Service(DRIVER), options=options)
    yield driver
    driver.quit()


def _errors(driver) -> list[dict]:
    return [e for e in driver.get_log("browser") if e["level"] in ("SEVERE", "ERROR")]


def _load_ms(driver) -> float:
    for _ in range(50):
        timing = driver.execute_script("const t = performance.getEntriesByType('navigation')[0];"
                                       "return t ? [t.loadEventEnd, t.startTime] : null;")
        if timing and timing[0] > 0:
            return timing[0] - timing[1]
        time.sleep(0.05)
    raise AssertionError("the page never reached its load event")


def test_the_leaderboard_sorts_filters_and_leads_to_an_episode(served, browser, tmp_path):
    from selenium.webdriver.common.by import By

    browser.get(f"{served}/index.html")
    _load_ms(browser)
    rows = lambda: [r for r in browser.find_elements(By.CSS_SELECTOR, "#board tbody tr") if r.is_displayed()]  # noqa: E731
    agents = lambda: [r.find_elements(By.TAG_NAME, "td")[0].text for r in rows()]  # noqa: E731
    assert sorted(agents()) == ["llm", "oracle", "random"]
    success = browser.find_element(By.XPATH, "//th[text()='success']")
    success.click()
    assert agents()[0] != "oracle" and agents()[-1] == "oracle"  # ascending: the oracle solves the most
    success.click()
    assert agents()[0] == "oracle"
    browser.find_element(By.ID, "board-filter").send_keys("random")
    assert agents() == ["random"]
    browser.find_element(By.ID, "board-filter").clear()
    browser.find_element(By.ID, "board-filter").send_keys(" ")  # an empty filter shows every row again
    assert len(rows()) == 3
    shots = Path(os.environ.get(SHOTS) or tmp_path)  # docs/images/site_*.png come from this test's run
    browser.save_screenshot(str(shots / "site_leaderboard.png"))
    # To the oracle's run, filter its episodes, open one.
    browser.get(f"{served}/runs/oracle/mini/index.html")
    _load_ms(browser)
    assert browser.find_element(By.CSS_SELECTOR, "svg.plot")
    episodes = browser.find_elements(By.CSS_SELECTOR, "#episodes tbody tr")
    assert len(episodes) == 2
    browser.save_screenshot(str(shots / "site_run.png"))
    browser.find_element(By.LINK_TEXT, "0").click()
    _load_ms(browser)
    browser.save_screenshot(str(shots / "site_episode.png"))
    images = browser.find_elements(By.CSS_SELECTOR, ".strip img")
    assert images and all(browser.execute_script("return arguments[0].complete && arguments[0].naturalWidth", i)
                          for i in images[:3])
    assert len(browser.find_elements(By.CSS_SELECTOR, "#decisions tbody tr")) >= 3
    assert _errors(browser) == []


def test_every_page_loads_without_console_errors(served, browser, site):
    for page in sorted(site.rglob("*.html")):
        browser.get(f"{served}/{page.relative_to(site)}")
        _load_ms(browser)
        assert _errors(browser) == [], page


def test_a_thousand_episode_run_builds_fast_and_its_pages_load_at_once(runs, browser, tmp_path):
    """A run of 1,000 episodes (the oracle's two, each written 500 times under other indices, keyframes
    included) builds, and its leaderboard and run page reach the load event quickly: images are referenced."""
    big = tmp_path / "big"
    shutil.copytree(runs["oracle"], big)
    records = [json.loads(line) for line in (runs["oracle"] / "episodes_mini.jsonl").read_text().splitlines()]
    results = json.loads((runs["oracle"] / "results.json").read_text())
    summary = results["splits"]["mini"]["episodes"]
    lines, episodes = [], []
    for i in range(1000):
        lines.append(json.dumps({**records[i % 2], "index": i}))
        episodes.append({**summary[i % 2], "index": i})
    (big / "episodes_mini.jsonl").write_text("\n".join(lines) + "\n")
    results["splits"]["mini"]["episodes"] = episodes
    results["protocol"] = None  # 1,000 indices: not the protocol's mini split
    (big / "results.json").write_text(json.dumps(results))
    out = tmp_path / "site"
    began = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "muble.app.cli", "site", str(big), f"--out={out}"],
                          capture_output=True, text=True, timeout=600)
    seconds = time.perf_counter() - began
    assert done.returncode == 0, done.stderr[-2000:]
    assert len(list((out / "runs" / "big" / "mini").glob("*.html"))) == 1001
    print(f"1,000-episode site built in {seconds:.1f} s")
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), functools.partial(Quiet, directory=str(tmp_path)))
    threading.Thread(target=server.serve_forever, daemon=True).start()
    try:
        url = f"http://127.0.0.1:{server.server_address[1]}/site"
        times = {}
        for page in ("index.html", "runs/big/mini/index.html", "runs/big/mini/000999.html"):
            browser.get(f"{url}/{page}")
            times[page] = _load_ms(browser)
            assert _errors(browser) == [], page
        print("load event (ms):", times)
        assert times["index.html"] < 1000 and times["runs/big/mini/index.html"] < 1000, times
        assert (out / "runs" / "big" / "mini" / "index.html").stat().st_size < 2_000_000
    finally:
        server.shutdown()
