"""Headless Chromium driven over the Chrome DevTools Protocol (a websocket,
websocket-client): open a page, evaluate JavaScript, take a screenshot.
The page's Bokeh widgets live in shadow roots; deep_js() finds an element
by a CSS class through them."""

from __future__ import annotations

import base64
import json
import os
import shutil
import subprocess
import tempfile
import time
import urllib.request
from pathlib import Path

import websocket

CHROMIUM_NAMES = ("chromium", "chromium-browser", "google-chrome")

# findDeep(cls): the host element with class cls, searched through every shadow root;
# textDeep(cls): the text it shows (its shadow root's, styles left out);
# inner(cls, sel): the first sel (input, select, button) inside that host's shadow root.
DEEP_JS = """
function findDeep(cls, root) {
  root = root || document;
  const hit = root.querySelector('.' + cls);
  if (hit) return hit;
  for (const el of root.querySelectorAll('*')) {
    if (el.shadowRoot) { const h = findDeep(cls, el.shadowRoot); if (h) return h; }
  }
  return null;
}
function textDeep(cls) {
  const host = findDeep(cls);
  if (!host) return null;
  if (!host.shadowRoot) return host.innerText;
  return Array.from(host.shadowRoot.children).filter(e => e.tagName !== 'STYLE').map(e => e.innerText).join('');
}
function inner(cls, sel) {
  const host = findDeep(cls);
  if (!host) return null;
  return (host.shadowRoot && host.shadowRoot.querySelector(sel)) || host.querySelector(sel);
}
"""


def find_chromium():
    """$LEVELER_CHROMIUM, else the first of CHROMIUM_NAMES on the PATH, else None."""
    if os.environ.get("LEVELER_CHROMIUM"):
        return os.environ["LEVELER_CHROMIUM"]
    for name in CHROMIUM_NAMES:
        path = shutil.which(name)
        if path:
            return path
    return None


class BrowserLost(RuntimeError):
    """Chromium's DevTools connection closed under us: the browser process died or the page
    target went away. The message carries the process's state and the tail of its output."""


class Browser:
    def __init__(self, chromium: str, profile: Path, width=1400, height=1500):
        self.args = (chromium, profile, width, height)
        self.profile = profile
        self.out_path = profile.parent / f"{profile.name}.chromium.out"
        self.out = open(self.out_path, "w")
        # Chromium keeps its singleton socket (and, with /dev/shm off, its shared memory) in
        # TMPDIR and leaves the folders there: a short one of our own (a socket path is at most
        # 107 bytes), removed by close()
        self.tmp = tempfile.mkdtemp(prefix="leveler-chromium-")
        self.proc = subprocess.Popen([chromium, "--headless=new", "--no-sandbox", "--disable-gpu",
                                      "--disable-dev-shm-usage", "--no-first-run", "--remote-debugging-port=0",
                                      f"--user-data-dir={profile}", f"--window-size={width},{height}",
                                      "about:blank"], stdout=self.out, stderr=subprocess.STDOUT,
                                     env=dict(os.environ, TMPDIR=self.tmp))
        port = self._devtools_port(timeout_s=30)
        # A page target of our own: the start-up about:blank tab may still be swapped for
        # another target while Chromium settles, which closes a connection made to it.
        req = urllib.request.Request(f"http://127.0.0.1:{port}/json/new?about:blank", method="PUT")
        with urllib.request.urlopen(req, timeout=10) as r:
            page = json.load(r)
        self.ws = websocket.create_connection(page["webSocketDebuggerUrl"], timeout=30)
        self.next_id = 0

    def _lost(self, exc):
        self.out.flush()
        state = "still running" if self.proc.poll() is None else f"exited with {self.proc.returncode}"
        tail = self.out_path.read_text(errors="replace")[-2000:]
        return BrowserLost(f"Chromium's DevTools connection closed ({exc}); the browser is {state}; "
                           f"{self.out_path} ends:\n{tail}")

    def _devtools_port(self, timeout_s):
        path = self.profile / "DevToolsActivePort"
        until = time.monotonic() + timeout_s
        while time.monotonic() < until:
            if self.proc.poll() is not None:
                raise RuntimeError(f"chromium exited with {self.proc.returncode}")
            if path.exists() and path.read_text().strip():
                return int(path.read_text().split()[0])
            time.sleep(0.1)
        raise RuntimeError(f"chromium wrote no {path} in {timeout_s} s")

    def call(self, method, **params):
        self.next_id += 1
        try:
            self.ws.send(json.dumps({"id": self.next_id, "method": method, "params": params}))
        except (websocket.WebSocketConnectionClosedException, BrokenPipeError, ConnectionError) as exc:
            raise self._lost(exc) from exc
        while True:
            try:
                msg = json.loads(self.ws.recv())
            except (websocket.WebSocketConnectionClosedException, ConnectionError) as exc:
                raise self._lost(exc) from exc
            if msg.get("id") == self.next_id:
                if "error" in msg:
                    raise RuntimeError(f"{method}: {msg['error']}")
                return msg["result"]

    def open(self, url):
        self.call("Page.enable")
        self.call("Page.navigate", url=url)

    def js(self, expression):
        """The value of a JavaScript expression in the page (DEEP_JS's helpers defined)."""
        r = self.call("Runtime.evaluate", expression=DEEP_JS + expression, returnByValue=True, awaitPromise=True)
        if "exceptionDetails" in r:
            raise RuntimeError(f"javascript: {r['exceptionDetails'].get('exception', r['exceptionDetails'])}")
        return r["result"].get("value")

    def wait_js(self, expression, timeout_s, step_s=0.2):
        """expression's first truthy value, or None after timeout_s."""
        until = time.monotonic() + timeout_s
        while True:
            value = self.js(expression)
            if value or time.monotonic() >= until:
                return value or None
            time.sleep(step_s)

    def screenshot(self, path: Path):
        data = self.call("Page.captureScreenshot", format="png", captureBeyondViewport=True)["data"]
        path.write_bytes(base64.b64decode(data))
        return path

    def restart(self):
        """This browser closed and a new one started in its place (a fresh profile beside the old)."""
        self.close()
        chromium, profile, width, height = self.args
        Browser.__init__(self, chromium, profile.with_name(profile.name + "-again"), width, height)

    def close(self):
        try:
            self.ws.close()
        except (websocket.WebSocketException, OSError):
            pass                                    # a lost connection: the process is still ours to stop
        finally:
            self.proc.terminate()
            try:
                self.proc.wait(10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
            self.out.close()
            shutil.rmtree(self.tmp, ignore_errors=True)
