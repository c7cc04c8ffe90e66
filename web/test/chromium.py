"""Headless Chromium driven over the DevTools protocol on a pipe (--remote-debugging-pipe): no
driver, no WebSocket library, only the standard library.

    with Chromium(width, height) as browser:
        browser.open(url)
        browser.wait_for("window.__photonlmReady === true", error="window.__photonlmError")
        png_bytes = browser.screenshot()
        assert not browser.console        # the page's warnings, errors and uncaught exceptions

Also serve(directory): the files of a directory over HTTP on 127.0.0.1 (a thread), as
`python3 -m http.server` serves them.
"""
import base64
import fcntl
import functools
import http.server
import json
import os
import shutil
import subprocess
import tempfile
import threading
import time

BROWSERS = ("chromium", "chromium-browser", "google-chrome")


class BrowserError(RuntimeError):
    pass


def find_browser():
    for name in [os.environ.get("PHOTONLM_CHROMIUM")] + list(BROWSERS):
        path = name and shutil.which(name)
        if path:
            return path
    raise BrowserError("no Chromium found (apt install chromium, or set PHOTONLM_CHROMIUM)")


def _high(fd):
    """fd moved to a number above 9 (not 3 or 4, which the pipe protocol's ends take in the child)."""
    high = fcntl.fcntl(fd, fcntl.F_DUPFD_CLOEXEC, 10)
    os.close(fd)
    return high


class Chromium:
    """A headless Chromium with one page of width x height CSS pixels at device scale 1; WebGL runs
    on SwiftShader (the CPU), the same on every machine."""

    def __init__(self, width, height, timeout=60.0):
        self.width, self.height, self.timeout = width, height, timeout
        self.next_id = 0
        self.buffer = b""
        self.session = None
        self.console = []   # the page's console warnings and errors, uncaught exceptions

    def __enter__(self):
        self.profile = tempfile.mkdtemp(prefix="photonlm-chromium-")
        to_child_r, to_child_w = (_high(fd) for fd in os.pipe())
        from_child_r, from_child_w = (_high(fd) for fd in os.pipe())
        args = ["--headless", "--remote-debugging-pipe", "--no-sandbox",
                "--user-data-dir=" + self.profile, "--no-first-run", "--no-default-browser-check",
                "--disable-extensions", "--disable-background-networking", "--disable-component-update",
                "--hide-scrollbars", "--mute-audio", "--force-color-profile=srgb", "--force-device-scale-factor=1",
                "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--ignore-gpu-blocklist",
                "--window-size=%d,%d" % (self.width, self.height), "about:blank"]
        self.log = open(os.path.join(self.profile, "chromium.log"), "w+")
        # The protocol's fds: Chromium reads commands from 3 and writes replies to 4.
        shell = 'exec "$0" "$@" 3<&%d 4>&%d %d<&- %d>&-' % (to_child_r, from_child_w, to_child_r, from_child_w)
        self.proc = subprocess.Popen(["bash", "-c", shell, find_browser()] + args, stdin=subprocess.DEVNULL,
                                     stdout=self.log, stderr=self.log, pass_fds=(to_child_r, from_child_w))
        os.close(to_child_r)
        os.close(from_child_w)
        self.write_fd, self.read_fd = to_child_w, from_child_r
        targets = self.call("Target.getTargets")["targetInfos"]
        pages = [t for t in targets if t["type"] == "page"]
        target = pages[0]["targetId"] if pages else self.call("Target.createTarget", url="about:blank")["targetId"]
        self.session = self.call("Target.attachToTarget", targetId=target, flatten=True)["sessionId"]
        self.call("Page.enable")
        self.call("Runtime.enable")
        self.call("Emulation.setDeviceMetricsOverride", width=self.width, height=self.height,
                  deviceScaleFactor=1, mobile=False)
        return self

    def __exit__(self, *exc):
        try:
            if self.proc.poll() is None:
                self.session = None
                self.call("Browser.close", wait=5.0)
        except (BrowserError, OSError):
            pass
        try:
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        os.close(self.write_fd)
        os.close(self.read_fd)
        self.log.close()
        shutil.rmtree(self.profile, ignore_errors=True)

    def browser_log(self):
        self.log.flush()
        self.log.seek(0)
        return self.log.read()[-4000:]

    def _message(self, deadline):
        while b"\0" not in self.buffer:
            if time.monotonic() > deadline:
                raise BrowserError("Chromium did not answer in time")
            chunk = os.read(self.read_fd, 1 << 20)
            if not chunk:
                raise BrowserError("Chromium closed its pipe:\n" + self.browser_log())
            self.buffer += chunk
        message, self.buffer = self.buffer.split(b"\0", 1)
        return json.loads(message)

    def call(self, method, wait=None, **params):
        """One protocol command; its result (raises on the protocol's errors)."""
        self.next_id += 1
        message = {"id": self.next_id, "method": method, "params": params}
        if self.session and not method.startswith(("Target.", "Browser.")):
            message["sessionId"] = self.session
        os.write(self.write_fd, json.dumps(message).encode() + b"\0")
        deadline = time.monotonic() + (wait or self.timeout)
        while True:
            reply = self._message(deadline)
            self._note(reply)
            if reply.get("id") == self.next_id:
                if "error" in reply:
                    raise BrowserError("%s: %s" % (method, reply["error"]))
                return reply.get("result", {})

    def _note(self, event):
        """Keeps the page's console warnings and errors and its uncaught exceptions."""
        method, params = event.get("method"), event.get("params", {})
        if method == "Runtime.consoleAPICalled" and params.get("type") in ("warning", "error", "assert"):
            text = " ".join(str(a.get("value", a.get("description", ""))) for a in params.get("args", []))
            self.console.append("%s: %s" % (params["type"], text))
        elif method == "Runtime.exceptionThrown":
            details = params.get("exceptionDetails", {})
            self.console.append("exception: %s" % details.get("exception", {}).get("description", details.get("text")))

    def evaluate(self, expression):
        result = self.call("Runtime.evaluate", expression=expression, returnByValue=True)
        if "exceptionDetails" in result:
            raise BrowserError("%s: %s" % (expression, result["exceptionDetails"]))
        return result["result"].get("value")

    def open(self, url):
        self.call("Page.navigate", url=url)

    def wait_for(self, condition, error=None, timeout=None):
        """Polls a JavaScript expression until it is true; raises with the page's `error`
        expression's value if that becomes set first."""
        deadline = time.monotonic() + (timeout or self.timeout)
        while time.monotonic() < deadline:
            if error:
                failure = self.evaluate(error)
                if failure:
                    raise BrowserError("the page failed: %s" % failure)
            if self.evaluate(condition):
                return
            time.sleep(0.05)
        raise BrowserError("the page was not ready in %.0f s (%s)" % (timeout or self.timeout, condition))

    def screenshot(self):
        """The page's pixels as PNG bytes (width x height)."""
        data = self.call("Page.captureScreenshot", format="png",
                         clip=dict(x=0, y=0, width=self.width, height=self.height, scale=1))["data"]
        return base64.b64decode(data)


class _QuietHandler(http.server.SimpleHTTPRequestHandler):
    extensions_map = dict(http.server.SimpleHTTPRequestHandler.extensions_map,
                          **{".js": "text/javascript", ".glb": "model/gltf-binary", ".map": "application/json"})

    def log_message(self, *args):
        pass


class serve:
    """`with serve(directory) as base_url:` the directory over HTTP on 127.0.0.1, a free port."""

    def __init__(self, directory):
        self.server = http.server.ThreadingHTTPServer(
            ("127.0.0.1", 0), functools.partial(_QuietHandler, directory=directory))
        self.thread = threading.Thread(target=self.server.serve_forever, daemon=True)

    def __enter__(self):
        self.thread.start()
        return "http://127.0.0.1:%d/" % self.server.server_address[1]

    def __exit__(self, *exc):
        self.server.shutdown()
        self.server.server_close()
        self.thread.join()
