#!/usr/bin/env python3
"""Drives headless Chromium over the DevTools protocol (``--remote-debugging-pipe``: JSON messages on
file descriptors 3 and 4, Python's standard library only, nothing downloaded) to check an HTML report at
given window widths, the way a reader's browser lays it out.

For each width W it loads the page in a W x 900 px viewport and
  - takes a full-page screenshot (the whole document height) to OUT_DIR/report-W.png;
  - measures horizontal overflow: the document's scroll width against the viewport width;
  - counts broken images (not complete or zero natural width) and images/figures without alt text;
  - collects console errors, uncaught exceptions and log entries of level "error".
It prints one JSON object per width on stdout and exits 0 when every width passes, 1 when a check
fails, 2 on usage errors or when the browser cannot be driven.

Usage: report_browser.py REPORT.html OUT_DIR [WIDTH ...]   (default widths: 800 1400)
"""

import base64
import json
import os
import subprocess
import sys
import tempfile
import time

BROWSER = "/usr/bin/chromium"
# Chromium cannot capture taller bitmaps reliably (GPU texture limit); longer pages are captured in
# slices and reported as several files.
# REPORT_SHOT_SLICE=PX cuts the screenshots into slices of PX (e.g. 2000, to look at them closely).
MAX_SHOT_HEIGHT = int(os.environ.get("REPORT_SHOT_SLICE", "16000"))


class Cdp:
    """A DevTools session over Chromium's remote-debugging pipe."""

    def __init__(self, user_data_dir):
        to_browser_r, to_browser_w = os.pipe()
        from_browser_r, from_browser_w = os.pipe()

        def child_fds():
            # Copies first, so that neither end is overwritten when os.pipe returned 3 or 4; os.dup2
            # makes 3 and 4 inheritable across exec.
            r, w = os.dup(to_browser_r), os.dup(from_browser_w)
            os.dup2(r, 3)
            os.dup2(w, 4)

        self.proc = subprocess.Popen(
            [
                BROWSER,
                "--headless",
                "--no-sandbox",
                "--disable-gpu",
                "--disable-quic",
                "--no-first-run",
                "--disable-background-networking",
                "--disable-component-update",
                "--disable-sync",
                "--hide-scrollbars",
                "--remote-debugging-pipe",
                f"--user-data-dir={user_data_dir}",
                "about:blank",
            ],
            # The child puts the pipe ends on fds 3 and 4 itself; close_fds would close them again.
            close_fds=False,
            preexec_fn=child_fds,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        os.close(to_browser_r)
        os.close(from_browser_w)
        self.w = os.fdopen(to_browser_w, "wb", buffering=0)
        self.r = os.fdopen(from_browser_r, "rb", buffering=0)
        self.buf = b""
        self.next_id = 0
        self.events = []

    def _read_message(self, deadline):
        while b"\0" not in self.buf:
            if time.time() > deadline:
                raise TimeoutError("no answer from chromium")
            chunk = self.r.read(65536)
            if not chunk:
                raise RuntimeError("chromium closed the DevTools pipe")
            self.buf += chunk
        raw, self.buf = self.buf.split(b"\0", 1)
        return json.loads(raw)

    def call(self, method, params=None, session=None, timeout=60):
        self.next_id += 1
        msg = {"id": self.next_id, "method": method, "params": params or {}}
        if session:
            msg["sessionId"] = session
        self.w.write(json.dumps(msg).encode() + b"\0")
        deadline = time.time() + timeout
        while True:
            m = self._read_message(deadline)
            if m.get("id") == self.next_id:
                if "error" in m:
                    raise RuntimeError(f"{method}: {m['error']}")
                return m.get("result", {})
            self.events.append(m)

    def wait_event(self, name, timeout=60):
        for i, e in enumerate(self.events):
            if e.get("method") == name:
                return self.events.pop(i)
        deadline = time.time() + timeout
        while True:
            m = self._read_message(deadline)
            if m.get("method") == name:
                return m
            self.events.append(m)

    def close(self):
        try:
            self.call("Browser.close", timeout=10)
        except Exception:
            pass
        try:
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()


MEASURE = """(() => {
  const d = document.documentElement;
  const imgs = [...document.images];
  const figs = [...document.querySelectorAll('figure')];
  const noAlt = figs.filter(f => {
    const i = f.querySelector('img');
    if (i) return !(i.getAttribute('alt') || '').trim();
    const r = f.querySelector('[role=img]');
    return !(r && (r.getAttribute('aria-label') || '').trim());
  }).length;
  const wide = [...document.body.querySelectorAll('*')]
    .filter(e => e.getBoundingClientRect().right > d.clientWidth + 1 && !e.closest('.table-wrap'))
    .slice(0, 5).map(e => e.tagName.toLowerCase() + (e.className ? '.' + e.className : ''));
  return JSON.stringify({
    scrollWidth: d.scrollWidth, clientWidth: d.clientWidth, height: d.scrollHeight,
    images: imgs.length, broken: imgs.filter(i => !i.complete || i.naturalWidth === 0).length,
    figures: figs.length, noAlt, sections: [...document.querySelectorAll('section[id]')].map(s => s.id),
    wide,
  });
})()"""


def check_width(cdp, session, url, width, out_dir):
    cdp.events = [e for e in cdp.events if e.get("sessionId") != session]
    cdp.call(
        "Emulation.setDeviceMetricsOverride",
        {"width": width, "height": 900, "deviceScaleFactor": 1, "mobile": False},
        session,
    )
    cdp.call("Page.navigate", {"url": url}, session)
    cdp.wait_event("Page.loadEventFired")
    m = json.loads(
        cdp.call("Runtime.evaluate", {"expression": MEASURE, "returnByValue": True}, session)[
            "result"
        ]["value"]
    )
    height = max(1, int(m["height"]))
    shots = []
    top = 0
    part = 0
    while top < height:
        h = min(MAX_SHOT_HEIGHT, height - top)
        data = cdp.call(
            "Page.captureScreenshot",
            {
                "format": "png",
                "captureBeyondViewport": True,
                "clip": {"x": 0, "y": top, "width": width, "height": h, "scale": 1},
            },
            session,
            timeout=120,
        )["data"]
        name = f"report-{width}.png" if top == 0 and h == height else f"report-{width}-{part + 1}.png"
        path = os.path.join(out_dir, name)
        with open(path, "wb") as f:
            f.write(base64.b64decode(data))
        shots.append(path)
        top += h
        part += 1
    errors = []
    for e in cdp.events:
        if e.get("sessionId") != session:
            continue
        method, p = e.get("method"), e.get("params", {})
        if method == "Runtime.consoleAPICalled" and p.get("type") in ("error", "assert"):
            errors.append("console: " + " ".join(str(a.get("value", a.get("description", ""))) for a in p.get("args", [])))
        elif method == "Runtime.exceptionThrown":
            errors.append("exception: " + p.get("exceptionDetails", {}).get("text", ""))
        elif method == "Log.entryAdded" and p.get("entry", {}).get("level") == "error":
            errors.append("log: " + p["entry"].get("text", ""))
    m.update({"width": width, "screenshots": shots, "console_errors": errors})
    failures = []
    if m["scrollWidth"] > m["clientWidth"]:
        failures.append(
            f"horizontal overflow: the page is {m['scrollWidth']} px wide in a {m['clientWidth']} px window"
            f" (widest elements: {', '.join(m['wide']) or 'unknown'})"
        )
    if m["broken"]:
        failures.append(f"{m['broken']} of {m['images']} images did not load")
    if m["noAlt"]:
        failures.append(f"{m['noAlt']} of {m['figures']} figures have no alt text")
    if errors:
        failures.append(f"{len(errors)} console error(s): {errors[:3]}")
    m["failures"] = failures
    return m


def main(argv):
    if len(argv) < 3 or argv[1] in ("-h", "--help"):
        print(__doc__, file=sys.stderr)
        return 2
    report, out_dir = argv[1], argv[2]
    try:
        widths = [int(w) for w in argv[3:]] or [800, 1400]
    except ValueError:
        print(f"error: widths must be integers in px, got {argv[3:]}", file=sys.stderr)
        return 2
    if not os.path.isfile(report):
        print(f"error: {report}: no such file (expected a report.html)", file=sys.stderr)
        return 2
    if not os.access(BROWSER, os.X_OK):
        print(f"error: {BROWSER} not found; install Debian's chromium (apt-get install -y chromium)", file=sys.stderr)
        return 2
    os.makedirs(out_dir, exist_ok=True)
    url = "file://" + os.path.abspath(report)
    failed = False
    with tempfile.TemporaryDirectory() as profile:
        cdp = Cdp(profile)
        try:
            targets = cdp.call("Target.getTargets")["targetInfos"]
            page = next(t for t in targets if t["type"] == "page")
            session = cdp.call("Target.attachToTarget", {"targetId": page["targetId"], "flatten": True})[
                "sessionId"
            ]
            for domain in ("Page", "Runtime", "Log"):
                cdp.call(f"{domain}.enable", {}, session)
            for width in widths:
                m = check_width(cdp, session, url, width, out_dir)
                print(json.dumps(m))
                failed |= bool(m["failures"])
        except (RuntimeError, TimeoutError, StopIteration, OSError) as e:
            print(f"error: driving chromium failed: {e}", file=sys.stderr)
            return 2
        finally:
            cdp.close()
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
