#!/usr/bin/env python3
"""The live page of `rephoto live` in headless Chromium: it updates without a reload.

Run by the ctest test live/live_browser_test, which serves a live session holding 3 registered
photos and a non-image, and adds 2 more photos once this script writes its signal file:
    /usr/bin/python3 live_page.py http://127.0.0.1:PORT SIGNAL_FILE
Checks: the page shows the 3 photos, the curve, the latest photo with its prediction and error
image (decoded), suggestions with their rephotos and poses, and the run's closed-loop plot
(RUN/closed_loop.svg, written by the test); the non-image is listed with its status. Then a marker is set on `window`, the signal file is written, and within 60 s the page
shows 5 registered photos, a 5-photo curve and the new latest photo while the marker is still
there (the same document: no reload). /api/live has the same photos in the same order. No
console error or uncaught exception. Exit code 0 when every check passed.
"""
import json
import os
import sys
import time
import urllib.request

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from benchmark_pages import Browser  # noqa: E402


def main():
    base, signal = sys.argv[1], sys.argv[2]
    failures = []

    def check(condition, message):
        if not condition:
            failures.append(message)

    browser = Browser(os.environ.get("CHROMIUM", "/usr/bin/chromium"))
    try:
        check(browser.open(base + "/") == 200, "live page: not HTTP 200")

        def state():
            return browser.evaluate("""({
              rows: Array.from(document.querySelectorAll('#photos tbody tr'),
                               r => [r.dataset.name, r.dataset.status]),
              dots: document.querySelectorAll('#curve circle[data-key=completeness]').length,
              latest: document.getElementById('latest-name')?.textContent ?? '',
              images: Array.from(document.querySelectorAll('#latest img, #suggestions img'),
                                 i => ({cls: i.className, ok: i.complete && i.naturalWidth > 0})),
              suggestions: Array.from(document.querySelectorAll('#suggestions figure code'),
                                      c => c.textContent),
              marker: window.__liveMarker ?? null,
              loop: (() => { const i = document.getElementById('closed-loop-plot');
                             return {shown: !document.getElementById('closed-loop').hidden,
                                     ok: !!i && i.complete && i.naturalWidth > 0}; })()})""")

        def wait_for(predicate, seconds):
            deadline = time.time() + seconds
            while time.time() < deadline:
                browser.evaluate("Promise.all(Array.from(document.images, i => i.decode().catch(() => 0)))")
                s = state()
                if predicate(s):
                    return s
                time.sleep(0.25)
            return state()

        registered = lambda s: [n for n, st in s["rows"] if st == "registered"]
        # The plot's section is shown by its load event, which can run after the image reports
        # complete: wait for it too.
        s = wait_for(lambda s: len(registered(s)) == 3 and all(i["ok"] for i in s["images"])
                     and s["loop"]["shown"], 30)
        check(len(registered(s)) == 3, f"before: expected 3 registered photos, got {s['rows']}")
        check(["notes.txt", "not_an_image"] in s["rows"], f"non-image status missing: {s['rows']}")
        check(s["dots"] == 3, f"before: curve has {s['dots']} completeness points, not 3")
        check(s["latest"].startswith("p2.png"), f"before: latest is '{s['latest']}'")
        kinds = sorted(i["cls"] for i in s["images"] if i["cls"].startswith("latest-"))
        check(kinds == ["latest-error", "latest-photo", "latest-prediction"],
              f"latest photo, prediction and error image expected, got {kinds}")
        check(all(i["ok"] for i in s["images"]), f"an image did not load: {s['images']}")
        check(len(s["suggestions"]) >= 1, "no suggestion shown")
        check(s["loop"]["shown"] and s["loop"]["ok"],
              f"the run's closed-loop plot is not shown: {s['loop']}")
        for text in s["suggestions"]:
            pose = json.loads(text)
            check(set(pose) == {"camera", "qvec", "tvec"} and len(pose["qvec"]) == 4,
                  f"suggestion pose not in the sidecar's shape: {text}")

        browser.evaluate("window.__liveMarker = 42")
        with open(signal, "w") as f:
            f.write("go\n")
        # The update replaces the images' sources: wait for them to load as well (checking right
        # after the rows changed failed now and then with every image still loading).
        s = wait_for(lambda s: len(registered(s)) == 5 and s["latest"].startswith("p4.png")
                     and all(i["ok"] for i in s["images"]), 60)
        check(s["marker"] == 42, "the page was reloaded (marker lost)")
        check(len(registered(s)) == 5, f"after: expected 5 registered photos, got {s['rows']}")
        check(s["dots"] == 5, f"after: curve has {s['dots']} completeness points, not 5")
        check(s["latest"].startswith("p4.png"), f"after: latest is '{s['latest']}'")
        check(all(i["ok"] for i in s["images"]), f"after: an image did not load: {s['images']}")
        with urllib.request.urlopen(base + "/api/live", timeout=30) as r:
            api = json.loads(r.read().decode())
        check([p["name"] for p in api["photos"]] == [n for n, _ in s["rows"]],
              "/api/live photos differ from the page's table")
        check(not browser.errors, "; ".join(browser.errors))
    finally:
        browser.close()
    for f in failures:
        print("FAIL:", f)
    if failures:
        return 1
    print("all checks passed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
