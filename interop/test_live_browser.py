"""radbench's live view (`campaign run --live`) in a real browser (headless Chromium, DevTools
protocol), as test_report_browser.py does for report.html.

A six-step campaign on radbench's built-in mock lab (loopback only) whose positioner is the
operator's prompt: the test is the operator, pressing Enter for each step only once the page has
shown the step before it, so the run is paced by the test and nothing depends on timing. The page,
opened from the URL radbench prints in its `--json` "live" event, must:
- update the range profile and the steps table as steps complete (counted in the DOM: each
  re-drawing bumps a `data-updates` attribute; the table's rows are counted);
- end with the six steps, the status "complete";
- log no console error or warning, no uncaught exception, no log entry of level error;
- request nothing but 127.0.0.1 on radbench's own port (and `data:` URLs);
- give a screenshot that is not blank.

Chromium is required: CI installs it (.ci/run); a missing browser fails, it never skips.
"""

import json
import os
import re
import select
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest

from test_report_browser import LIMIT_S, RADBENCH, REPO, WINDOW, Browser

STEPS = 6


@pytest.fixture
def browser(tmp_path):
    # Every host name unresolvable but the loopback radbench serves on.
    b = Browser(tmp_path / "profile", resolver_rules="MAP * ~NOTFOUND, EXCLUDE 127.0.0.1")
    yield b
    b.close()


def prompt_spec(tmp_path: Path) -> Path:
    """examples/accuracy.toml with the operator's prompt as its positioner."""
    text = (REPO / "examples" / "accuracy.toml").read_text()
    text = re.sub(r"^# \[positioner\].*$", '[positioner]\nkind = "prompt"', text, count=1, flags=re.M)
    assert 'kind = "prompt"' in text
    spec = tmp_path / "accuracy-prompt.toml"
    spec.write_text(text)
    return spec


def read_line(proc, deadline) -> str:
    line = b""
    while not line.endswith(b"\n"):
        left = deadline - time.monotonic()
        assert left > 0, "radbench printed no live event in time"
        ready, _, _ = select.select([proc.stdout], [], [], left)
        if ready:
            c = os.read(proc.stdout.fileno(), 1)
            assert c, "radbench closed its stdout"
            line += c
    return line.decode()


def wait_for(browser, expression, what):
    deadline = time.monotonic() + LIMIT_S
    while True:
        value = browser.evaluate(expression)
        if value:
            return value
        assert time.monotonic() < deadline, f"{what} within {LIMIT_S} s"
        time.sleep(0.05)


def page_counts(browser) -> dict:
    return browser.evaluate(
        """(() => ({
            rows: document.querySelectorAll('#steps tbody tr').length,
            table: Number(document.getElementById('steps').getAttribute('data-updates')),
            profile: Number(document.getElementById('profile').getAttribute('data-updates')),
            lines: document.querySelectorAll('#profile polyline.level').length,
            status: document.getElementById('status').textContent,
            current: document.getElementById('current').textContent,
            frames: window.radbenchFrames,
        }))()"""
    )


def faults(browser, origin: str):
    """Console errors and warnings, exceptions, error log entries, requests beyond `origin`."""
    out = []
    for e in browser.events:
        m, p = e["method"], e.get("params", {})
        if m == "Runtime.consoleAPICalled" and p.get("type") in ("error", "warning", "assert"):
            out.append(f"console.{p['type']}: {p.get('args')}")
        elif m == "Runtime.exceptionThrown":
            out.append(f"exception: {p.get('exceptionDetails')}")
        elif m == "Log.entryAdded" and p["entry"].get("level") in ("error", "warning"):
            out.append(f"log: {p['entry'].get('text')} {p['entry'].get('url', '')}")
        elif m == "Network.requestWillBeSent":
            url = p["request"]["url"]
            if not (url.startswith(origin + "/") or url.startswith("data:")):
                out.append(f"request: {url}")
    return out


def check_round_ticks_and_titles(browser):
    """Every tick a round value (1, 2 or 5 times a power of ten, times an integer), evenly
    spaced; the profile's title a name, not a CSV column."""
    axes = browser.evaluate(
        """(() => ['profile', 'plot'].flatMap(id => ['tick-x', 'tick-y'].map(c =>
            Array.from(document.querySelectorAll('#' + id + ' text.' + c)).map(t => t.textContent))))()"""
    )
    assert len(axes) == 4 and all(len(a) >= 3 for a in axes), axes
    for texts in axes:
        values = [float(t) for t in texts]
        steps = {round(b - a, 9) for a, b in zip(values, values[1:])}
        assert len(steps) == 1, texts
        step = steps.pop()
        mantissa = step / 10 ** np.floor(np.log10(step))
        assert any(abs(mantissa - m) < 1e-6 for m in (1, 2, 5)), (step, texts)
        assert all(abs(v / step - round(v / step)) < 1e-6 for v in values), texts
    title = browser.evaluate("document.getElementById('profile-title').textContent")
    assert "_db" not in title and "(dB)" in title, title


def test_live_page_follows_a_campaign(browser, tmp_path):
    spec = prompt_spec(tmp_path)
    out = tmp_path / "run"
    proc = subprocess.Popen(
        [RADBENCH, "campaign", "run", str(spec), "--allow-rf", "--out", str(out), "--json", "--live"],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    try:
        event = json.loads(read_line(proc, time.monotonic() + LIMIT_S))
        assert event["event"] == "live", event
        url = event["url"]
        origin = re.match(r"^(http://127\.0\.0\.1:\d+)/\?token=[0-9a-f]{32}$", url)
        assert origin, url
        origin = origin.group(1)
        browser.open(url)
        wait_for(browser, "window.radbenchFrames > 0", "the first frame")
        seen = []
        for k in range(1, STEPS + 1):
            proc.stdin.write(b"\n")
            proc.stdin.flush()
            wait_for(
                browser,
                f"document.getElementById('current').textContent.startsWith('step {k}/{STEPS}')",
                f"step {k} on the page",
            )
            seen.append(page_counts(browser))
        wait_for(browser, "document.getElementById('status').textContent === 'complete'", "complete")
        last = page_counts(browser)
        seen.append(last)
        proc.stdin.close()
        assert proc.wait(timeout=LIMIT_S) == 0, proc.stderr.read().decode()
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(timeout=10)
    rows = [s["rows"] for s in seen]
    # The table grew as steps completed (the runner finishes a step while the next ones are
    # captured, so it trails the prompts by up to two steps), and ended with all of them.
    assert rows == sorted(rows), rows
    assert rows[-1] == STEPS, rows
    assert len(set(rows)) >= 4, f"the table grew in steps: {rows}"
    assert last["table"] >= 4, last
    assert last["profile"] >= 4, f"the profile was drawn again as steps completed: {last}"
    assert last["lines"] == 1, last
    results = json.loads((out / "results.json").read_text())
    assert len(results["steps"]) == STEPS
    check_round_ticks_and_titles(browser)
    img = browser.screenshot()
    assert img.shape == (WINDOW[1], WINDOW[0])
    dark = (img < 128).mean()
    assert img.std() > 10, f"screenshot looks blank (std {img.std():.1f})"
    assert dark > 0.005, f"screenshot looks blank ({dark:.4f} dark)"
    assert faults(browser, origin) == []


def test_live_page_refuses_a_wrong_token(browser, tmp_path):
    """The page without its token is a 403 (Chromium logs the failed load: the checks see it)."""
    spec = prompt_spec(tmp_path)
    proc = subprocess.Popen(
        [RADBENCH, "campaign", "run", str(spec), "--allow-rf", "--out", str(tmp_path / "run"),
         "--json", "--live"],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    try:
        url = json.loads(read_line(proc, time.monotonic() + LIMIT_S))["url"]
        browser.open(url.split("?")[0] + "?token=" + "0" * 32)
        text = browser.evaluate("document.body ? document.body.textContent : ''")
        assert "403" in text, text
        assert browser.evaluate("typeof window.radbenchFrames") == "undefined"
    finally:
        proc.kill()
        proc.wait(timeout=10)
