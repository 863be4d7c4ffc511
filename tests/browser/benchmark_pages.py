#!/usr/bin/env python3
"""Opens the benchmark's pages in headless Chromium and checks the DOM after the scripts ran.

Drives Debian's /usr/bin/chromium through the Chrome DevTools protocol directly (Debian's
python3-websocket; no browser download, no npm). Run by the ctest test
service/pages_browser_test, which starts a server with one dataset ("tiny") and two scored
submissions ("exact": renders equal to the photos, "noisy") and passes its base URL:
    /usr/bin/python3 benchmark_pages.py http://127.0.0.1:PORT
Checks: the dataset list links the dataset; the dataset page links its downloads; the
leaderboard states its ranking rule, lists both submissions best first and re-sorts when a
header is clicked; the submission page shows its scores table and no image (nothing per test
photo, nothing derived from a secret photo's pixels: issue 27); every
same-origin link and image on these pages loads (HTTP 200, images decoded); no console error or
uncaught exception; the leaderboard has its rows with JavaScript disabled too.
Exit code 0 when every check passed, 1 otherwise (each failure printed on one line).
"""
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time

import websocket  # Debian python3-websocket (websocket-client)


class Browser:
    """Headless Chromium with one page, spoken to over the DevTools protocol."""

    def __init__(self, chromium, flags=("--disable-gpu",), width=None, height=None, timeout=60):
        """`flags`: Chromium options beyond the headless basics (the default draws without a
        GPU; view3d_check.py passes SwiftShader's for WebGL). `width` x `height`: the window
        and viewport size, when given. `timeout`: seconds a DevTools call may take."""
        self.profile = tempfile.mkdtemp(prefix="rephoto-chromium-")
        size = [f"--window-size={width},{height}"] if width else []
        # Chromium's own temporary folders (org.chromium.Chromium.*) go inside the profile,
        # which close() removes; in $TMPDIR they stayed behind after every run.
        scratch = os.path.join(self.profile, "tmp")
        os.mkdir(scratch)
        self.process = subprocess.Popen(
            [chromium, "--headless", "--no-sandbox", *flags, *size, "--no-first-run",
             "--no-default-browser-check", "--disable-extensions", "--remote-debugging-port=0",
             "--user-data-dir=" + self.profile, "about:blank"],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
            env={**os.environ, "TMPDIR": scratch}, start_new_session=True)
        self.url = ""
        port_file = os.path.join(self.profile, "DevToolsActivePort")
        deadline = time.time() + 60
        while not (os.path.exists(port_file) and open(port_file).read().count("\n") >= 1):
            if time.time() > deadline or self.process.poll() is not None:
                raise RuntimeError("chromium did not open its DevTools port")
            time.sleep(0.05)
        port = open(port_file).read().split("\n")[0].strip()
        targets = json.loads(self._http(f"http://127.0.0.1:{port}/json/list"))
        page = next(t for t in targets if t.get("type") == "page")
        self.ws = websocket.create_connection(page["webSocketDebuggerUrl"], timeout=timeout)
        self.next_id = 0
        self.errors = []
        self.events = []
        for domain in ("Page", "Runtime", "Log"):
            self.call(domain + ".enable")
        if width:
            self.call("Emulation.setDeviceMetricsOverride", width=width, height=height,
                      deviceScaleFactor=1, mobile=False)

    @staticmethod
    def _http(url):
        import urllib.request
        with urllib.request.urlopen(url, timeout=30) as response:
            return response.read().decode()

    def _handle(self, message):
        method = message.get("method", "")
        params = message.get("params", {})
        if method == "Runtime.exceptionThrown":
            details = params.get("exceptionDetails", {})
            text = details.get("exception", {}).get("description") or details.get("text")
            self.errors.append(f"uncaught exception on {self.url}: {text}")
        elif method == "Runtime.consoleAPICalled" and params.get("type") == "error":
            text = " ".join(str(a.get("value", a.get("description", ""))) for a in params["args"])
            self.errors.append(f"console error on {self.url}: {text}")
        elif method == "Log.entryAdded" and params.get("entry", {}).get("level") == "error":
            self.errors.append(f"console error on {self.url}: {params['entry'].get('text')}")
        self.events.append(method)

    def call(self, method, **params):
        self.next_id += 1
        self.ws.send(json.dumps({"id": self.next_id, "method": method, "params": params}))
        while True:
            message = json.loads(self.ws.recv())
            if message.get("id") == self.next_id:
                if "error" in message:
                    raise RuntimeError(f"{method}: {message['error']}")
                return message.get("result", {})
            self._handle(message)

    def wait_for_event(self, name, seconds=60):
        deadline = time.time() + seconds
        while name not in self.events:
            if time.time() > deadline:
                raise RuntimeError(f"no {name} within {seconds} s")
            self.ws.settimeout(max(0.1, deadline - time.time()))
            self._handle(json.loads(self.ws.recv()))
        self.ws.settimeout(60)

    def evaluate(self, expression):
        result = self.call("Runtime.evaluate", expression=expression, returnByValue=True,
                           awaitPromise=True)
        if "exceptionDetails" in result:
            raise RuntimeError(f"{expression[:60]}...: {result['exceptionDetails']}")
        return result["result"].get("value")

    def open(self, url):
        """Loads `url` and waits for the load event and every image; returns the HTTP status."""
        self.url = url
        self.events.clear()
        self.call("Page.navigate", url=url)
        self.wait_for_event("Page.loadEventFired")
        self.evaluate("Promise.all(Array.from(document.images, i => i.decode().catch(() => 0)))")
        return self.evaluate(
            "performance.getEntriesByType('navigation')[0]?.responseStatus ?? 200")

    def screenshot(self):
        """The page as PNG bytes."""
        import base64
        return base64.b64decode(self.call("Page.captureScreenshot", format="png")["data"])

    def close(self):
        try:
            self.ws.close()
        finally:
            self.process.terminate()
            try:
                self.process.wait(10)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
            # Chromium's helper processes (its own process group) can still be writing into the
            # profile after the browser exits: stop them, then remove the profile (retried
            # while a late write lands).
            try:
                os.killpg(self.process.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            for _ in range(20):
                shutil.rmtree(self.profile, ignore_errors=True)
                if not os.path.exists(self.profile):
                    break
                time.sleep(0.1)


def main():
    base = sys.argv[1]
    chromium = os.environ.get("CHROMIUM", "/usr/bin/chromium")
    failures = []

    def check(condition, message):
        if not condition:
            failures.append(message)

    browser = Browser(chromium)
    try:
        def links_and_images():
            """Every same-origin link answers 200; every image decoded."""
            page = browser.evaluate("""({
              links: Array.from(document.querySelectorAll('a[href]'), a => a.href)
                .filter(href => href.startsWith(location.origin)),
              images: Array.from(document.images,
                                 img => ({src: img.src, ok: img.complete && img.naturalWidth > 0}))
            })""")
            for href in page["links"]:
                status = browser.evaluate(f"fetch({json.dumps(href)}).then(r => r.status)")
                check(status == 200, f"broken link {href} (HTTP {status}) on {browser.url}")
            for image in page["images"]:
                check(image["ok"], f"broken image {image['src']} on {browser.url}")
            return page

        def open_page(path):
            status = browser.open(base + path)
            check(status == 200, f"{path}: HTTP {status}")

        def count(selector):
            return browser.evaluate(f"document.querySelectorAll({json.dumps(selector)}).length")

        open_page("/")
        check(count('table#datasets a[href="/datasets/tiny"]') == 1,
              "dataset list: no link to tiny")
        links_and_images()

        open_page("/datasets/tiny")
        downloads = browser.evaluate(
            "Array.from(document.querySelectorAll('ul.downloads a'), a => a.textContent)")
        check(downloads == ["test-cameras.tar", "training.tar"],
              f"dataset page downloads: {downloads}")
        check(count("table#test-images tbody tr") == 2, "dataset page: not 2 test images")
        check("curl" in browser.evaluate("document.documentElement.outerHTML"),
              "dataset page: no curl example")
        links_and_images()

        open_page("/datasets/tiny/leaderboard")
        methods_js = ("Array.from(document.querySelectorAll("
                      "'table#leaderboard tbody tr td:nth-child(2)'), td => td.textContent)")
        methods = browser.evaluate(methods_js)
        check(methods == ["exact", "noisy"], f"leaderboard order: {methods}")
        check("filled" in (browser.evaluate("document.querySelector('p#ranking')?.textContent")
                           or ""), "leaderboard: no ranking rule stated")
        check(count("img") == 0, "leaderboard: an image")
        # Click "1-ncc mean" (4th column): ascending, then descending.
        click = "document.querySelector('table#leaderboard th:nth-child(4)').click()"
        browser.evaluate(click)
        check(browser.evaluate(methods_js) == ["exact", "noisy"], "sort ascending failed")
        browser.evaluate(click)
        methods = browser.evaluate(methods_js)
        check(methods == ["noisy", "exact"], f"sort descending: {methods}")
        submission_links = [h for h in links_and_images()["links"] if "/submissions/" in h]
        check(len(submission_links) == 2, f"leaderboard: {len(submission_links)} submission links")

        for href in submission_links:
            open_page(href[len(base):])
            check(browser.evaluate("document.querySelector('#status')?.textContent") == "done",
                  f"{href}: not done")
            check(count("table#scores tbody tr") == 3, f"{href}: not 3 score rows")
            images = links_and_images()["images"]
            check(len(images) == 0, f"{href}: {len(images)} images")

        # Without JavaScript the server-rendered rows are all there.
        browser.call("Emulation.setScriptExecutionDisabled", value=True)
        open_page("/datasets/tiny/leaderboard")
        check(count("table#leaderboard tbody tr") == 2, "no rows without JavaScript")
        failures.extend(browser.errors)
    finally:
        browser.close()
    for failure in failures:
        print(f"FAIL {failure}")
    print(f"{len(failures)} check(s) failed" if failures else "all checks passed")
    sys.exit(1 if failures else 0)


if __name__ == "__main__":
    main()
