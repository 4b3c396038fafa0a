"""radbench's campaign report.html in a real browser (headless Chromium, DevTools protocol).

Runs small campaigns on radbench's built-in mock lab (loopback only), opens each unmodified
report.html from disk in headless Chromium driven over `--remote-debugging-pipe` (every host name
unresolvable, so an external resource could not load anyway) and checks:
- no console error or warning, no uncaught exception, no log entry of level error;
- no request other than the file itself (no http(s), no other file; a heat map's inline
  `data:image/png` is part of the file);
- every plot an SVG element (parsed as SVG), laid out with a non-zero size, visible, with shapes
  drawn, as many as the file holds;
- every step's link figure (constellation and channel estimate or phase trajectory) likewise, with
  its points drawn and its EVM and MER in its caption;
- the summary (verdict, operator, instruments) laid out above the first figure, in the DOM and
  on the page;
- a 30-step run's heat map (an inline PNG, `data:` URI) decoded and shown, below the summary;
- a screenshot that is not blank (pixel variance, dark pixels).
A control page with a console error and an external image proves the checks see such faults.

Chromium is required: CI installs it (.ci/run); a missing browser fails, it never skips.
"""

import base64
import fcntl
import io
import json
import os
import re
import select
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

REPO = Path(__file__).resolve().parent.parent
RADBENCH = os.environ.get("RADBENCH_BIN", str(REPO / "target" / "debug" / "radbench"))
#: Longest one radbench invocation, or one browser session, may take, seconds.
LIMIT_S = 60
WINDOW = (1200, 1600)

# Evaluated in the page once loaded: every plot's element, size and visibility.
PROBE = """
(() => Array.from(document.querySelectorAll('figure.plot')).map(f => {
  const svg = f.querySelector('svg');
  const r = svg ? svg.getBoundingClientRect() : {width: 0, height: 0};
  const s = svg ? getComputedStyle(svg) : null;
  return {
    id: f.id,
    svg: !!svg && svg.namespaceURI === 'http://www.w3.org/2000/svg',
    width: r.width, height: r.height,
    visible: !!s && s.display !== 'none' && s.visibility !== 'hidden' && s.opacity !== '0',
    shapes: svg ? svg.querySelectorAll('circle, polyline, path, line').length : 0,
  };
}))()
"""


# Every step's link figure (constellation, channel estimate or phase trajectory): its inline SVG,
# laid out, visible, with its points drawn.
LINK_PROBE = """
(() => Array.from(document.querySelectorAll('figure.link')).map(f => {
  const svg = f.querySelector('svg');
  const r = svg ? svg.getBoundingClientRect() : {width: 0, height: 0};
  const s = svg ? getComputedStyle(svg) : null;
  const cap = f.querySelector('figcaption');
  return {
    id: f.id,
    svg: !!svg && svg.namespaceURI === 'http://www.w3.org/2000/svg',
    width: r.width, height: r.height,
    visible: !!s && s.display !== 'none' && s.visibility !== 'hidden' && s.opacity !== '0',
    points: svg ? svg.querySelectorAll('circle').length : 0,
    caption: cap ? cap.textContent : '',
  };
}))()
"""


# The summary and the first figure: their order in the DOM and their place on the page.
SUMMARY_PROBE = """
(() => {
  const s = document.querySelector('#summary');
  const f = document.querySelector('figure');
  if (!s || !f) return {summary: !!s, figure: !!f};
  return {
    summary: true, figure: true,
    before: !!(s.compareDocumentPosition(f) & Node.DOCUMENT_POSITION_FOLLOWING),
    summary_bottom: s.getBoundingClientRect().bottom + window.scrollY,
    figure_top: f.getBoundingClientRect().top + window.scrollY,
    verdict: (s.querySelector('.verdict') || {}).textContent || '',
    text: s.textContent,
  };
})()
"""

# A heat map's inline PNG: decoded, laid out, visible.
HEATMAP_PROBE = """
(() => Array.from(document.querySelectorAll('figure.heatmap img')).map(i => {
  const r = i.getBoundingClientRect();
  return {complete: i.complete, natural: i.naturalWidth, width: r.width, height: r.height};
}))()
"""


def check_summary_first(browser):
    s = browser.evaluate(SUMMARY_PROBE)
    assert s["summary"] and s["figure"], s
    assert s["before"], "the summary comes before the first figure in the DOM"
    assert s["summary_bottom"] <= s["figure_top"], s
    assert re.match(r"(PASS|FAIL|No verdict)", s["verdict"]), s
    for fact in ["Operator", "AWG *IDN?", "Scope *IDN?", "Worst error", "False targets"]:
        assert fact in s["text"], (fact, s["text"])


def chromium() -> str:
    path = os.environ.get("CHROMIUM_BIN") or shutil.which("chromium")
    if not path:
        pytest.fail(
            "chromium not found: install it (`apt-get install -y --no-install-recommends chromium`, "
            "as .ci/run does) or point CHROMIUM_BIN at it; this check never skips"
        )
    return path


ON_FDS_3_4 = (
    "import os, sys; os.dup2(int(sys.argv[1]), 3); os.dup2(int(sys.argv[2]), 4); "
    "os.execvp(sys.argv[3], sys.argv[3:])"
)


def high(fd: int) -> int:
    """`fd` moved to a descriptor number of 10 or more."""
    moved = fcntl.fcntl(fd, fcntl.F_DUPFD, 10)
    os.close(fd)
    return moved


class Browser:
    """Headless Chromium over the DevTools pipe (fd 3: commands in, fd 4: replies out)."""

    def __init__(self, profile: Path, resolver_rules: str = "MAP * ~NOTFOUND"):
        to_chrome_r, self.to_chrome = os.pipe()
        self.from_chrome, from_chrome_w = os.pipe()
        # Above 4, so the shell's redirections onto 3 and 4 cannot overwrite one another.
        to_chrome_r, from_chrome_w = (high(to_chrome_r), high(from_chrome_w))
        args = [
            chromium(),
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--no-first-run",
            "--no-default-browser-check",
            "--hide-scrollbars",
            "--remote-debugging-pipe",
            f"--user-data-dir={profile}",
            f"--host-resolver-rules={resolver_rules}",
            f"--window-size={WINDOW[0]},{WINDOW[1]}",
            "about:blank",
        ]
        # A small Python launcher puts the pipe ends on fds 3 and 4, where Chromium expects them.
        self.proc = subprocess.Popen(
            [sys.executable, "-c", ON_FDS_3_4, str(to_chrome_r), str(from_chrome_w), *args],
            pass_fds=(to_chrome_r, from_chrome_w),
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        os.close(to_chrome_r)
        os.close(from_chrome_w)
        self.buffer = b""
        self.next_id = 0
        self.events = []
        self.deadline = time.monotonic() + LIMIT_S
        target = self.call("Target.createTarget", {"url": "about:blank"})["targetId"]
        self.session = self.call(
            "Target.attachToTarget", {"targetId": target, "flatten": True}
        )["sessionId"]
        for domain in ["Page", "Runtime", "Log", "Network"]:
            self.call(f"{domain}.enable", session=True)
        self.call(
            "Emulation.setDeviceMetricsOverride",
            {"width": WINDOW[0], "height": WINDOW[1], "deviceScaleFactor": 1, "mobile": False},
            session=True,
        )

    def _message(self) -> dict:
        while b"\0" not in self.buffer:
            left = self.deadline - time.monotonic()
            if left <= 0:
                raise TimeoutError("chromium did not answer in time")
            ready, _, _ = select.select([self.from_chrome], [], [], left)
            if ready:
                chunk = os.read(self.from_chrome, 1 << 16)
                if not chunk:
                    raise RuntimeError(f"chromium closed the pipe (status {self.proc.poll()})")
                self.buffer += chunk
        line, self.buffer = self.buffer.split(b"\0", 1)
        return json.loads(line)

    def call(self, method: str, params=None, session=False) -> dict:
        self.next_id += 1
        msg = {"id": self.next_id, "method": method, "params": params or {}}
        if session:
            msg["sessionId"] = self.session
        os.write(self.to_chrome, json.dumps(msg).encode() + b"\0")
        while True:
            m = self._message()
            if m.get("id") == self.next_id:
                if "error" in m:
                    raise RuntimeError(f"{method}: {m['error']}")
                return m["result"]
            if "method" in m:
                self.events.append(m)

    def open(self, url: str):
        """Navigates and waits for the load event."""
        self.call("Page.navigate", {"url": url}, session=True)
        while not any(e["method"] == "Page.loadEventFired" for e in self.events):
            m = self._message()
            if "method" in m:
                self.events.append(m)

    def evaluate(self, expression: str):
        r = self.call(
            "Runtime.evaluate", {"expression": expression, "returnByValue": True}, session=True
        )
        assert "exceptionDetails" not in r, r
        return r["result"]["value"]

    def screenshot(self) -> np.ndarray:
        png = base64.b64decode(self.call("Page.captureScreenshot", {"format": "png"}, True)["data"])
        return np.asarray(Image.open(io.BytesIO(png)).convert("L"), dtype=float)

    def faults(self, page: Path):
        """Console errors and warnings, exceptions, error log entries, and requests for anything
        but `page` itself."""
        out = []
        for e in self.events:
            m, p = e["method"], e.get("params", {})
            if m == "Runtime.consoleAPICalled" and p.get("type") in ("error", "warning", "assert"):
                out.append(f"console.{p['type']}: {p.get('args')}")
            elif m == "Runtime.exceptionThrown":
                out.append(f"exception: {p.get('exceptionDetails')}")
            elif m == "Log.entryAdded" and p["entry"].get("level") in ("error", "warning"):
                out.append(f"log: {p['entry'].get('text')} {p['entry'].get('url', '')}")
            elif m == "Network.requestWillBeSent" and p["request"]["url"] != page.as_uri() \
                    and not p["request"]["url"].startswith("data:image/png;base64,"):
                out.append(f"request: {p['request']['url']}")
            elif m == "Network.loadingFailed":
                out.append(f"failed: {p.get('errorText')}")
        return out

    def close(self):
        try:
            self.call("Browser.close")
        except (RuntimeError, TimeoutError, OSError):
            pass
        try:
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait(timeout=10)
        os.close(self.to_chrome)
        os.close(self.from_chrome)


@pytest.fixture
def browser(tmp_path):
    b = Browser(tmp_path / "profile")
    yield b
    b.close()


@pytest.fixture(scope="module", params=["link", "music", "accuracy"])
def run_dir(request, tmp_path_factory):
    out = tmp_path_factory.mktemp(request.param) / "run"
    spec = REPO / "examples" / f"{request.param}.toml"
    done = subprocess.run(
        [RADBENCH, "campaign", "run", str(spec), "--allow-rf", "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=LIMIT_S,
        stdin=subprocess.DEVNULL,
    )
    assert done.returncode == 0, done.stderr
    assert (out / "report.html").is_file()
    return out


def test_the_checks_see_a_console_error_and_an_external_resource(browser, tmp_path):
    page = tmp_path / "bad.html"
    page.write_text(
        '<!DOCTYPE html><html><body><p>x</p><img src="http://example.com/x.png"/>'
        '<script>console.error("boom")</script></body></html>'
    )
    browser.open(page.as_uri())
    faults = browser.faults(page)
    assert any("console.error" in f for f in faults), faults
    assert any("example.com" in f for f in faults), faults


def test_report_html_in_chromium(run_dir, browser):
    page = run_dir / "report.html"
    html = page.read_text(encoding="utf-8")
    expected = re.findall(r'<figure id="([a-z-]+)" class="plot">', html)
    assert expected, "the report has no plot"
    browser.open(page.as_uri())
    plots = browser.evaluate(PROBE)
    assert [p["id"] for p in plots] == expected
    for p in plots:
        assert p["svg"], p
        assert p["visible"], p
        assert p["width"] > 100 and p["height"] > 50, p
        assert p["shapes"] > 5, p
    # Every step's link figure (each example sends data), as the file holds them.
    links = re.findall(r'<figure id="(link-step-\d{3})" class="link">', html)
    assert links, "the report shows no step's link"
    shown = browser.evaluate(LINK_PROBE)
    assert [p["id"] for p in shown] == links
    for p in shown:
        assert p["svg"] and p["visible"], p
        assert p["width"] > 100 and p["height"] > 50, p
        assert p["points"] > 20, p
        assert "EVM" in p["caption"] and "MER" in p["caption"], p
    check_summary_first(browser)
    img = browser.screenshot()
    assert img.shape == (WINDOW[1], WINDOW[0])
    dark = (img < 128).mean()
    assert img.std() > 10, f"screenshot looks blank (std {img.std():.1f})"
    assert dark > 0.005, f"screenshot looks blank ({dark:.4f} dark)"
    assert browser.faults(page) == []


def test_a_30_step_report_draws_a_heat_map_below_the_summary(browser, tmp_path):
    spec = tmp_path / "thirty.toml"
    spec.write_text(
        'name = "thirty"\n[sweep]\nparameter = "position"\nstart = 0.8\nstep = 0.02\ncount = 30\n'
    )
    out = tmp_path / "run"
    done = subprocess.run(
        [RADBENCH, "campaign", "run", str(spec), "--allow-rf", "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=LIMIT_S,
        stdin=subprocess.DEVNULL,
    )
    assert done.returncode == 0, done.stderr
    page = out / "report.html"
    browser.open(page.as_uri())
    check_summary_first(browser)
    maps = browser.evaluate(HEATMAP_PROBE)
    assert len(maps) == 1, maps
    m = maps[0]
    assert m["complete"] and m["natural"] > 100, m
    assert m["width"] > 100 and m["height"] > 50, m
    assert browser.faults(page) == []
