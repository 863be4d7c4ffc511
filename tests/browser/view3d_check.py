#!/usr/bin/env python3
"""Checks a rephoto report's 3D view (src/rephoto/report/view3d.h) in headless Chromium.

Drives Debian's /usr/bin/chromium through the DevTools protocol (Debian's python3-websocket),
with software WebGL (SwiftShader through ANGLE: --use-angle=swiftshader
--enable-unsafe-swiftshader; Chromium's GPU process falls back to it on a machine without a
GPU). Usage:
    /usr/bin/python3 view3d_check.py REPORT.html [--screenshot OUT.png] [--width 1280]
        [--height 900] [--note-visible] [--min-checks 3]
Checks, on the first 3D view of the page (element .view3d):
  1. it starts (data-ready="1"), no console error or uncaught exception; the time from
     navigation to the view's first frame is printed ("load+draw S s");
  2. colours: three vertices of the first model are chosen from the page's data block
     (positions and errors decoded here from its base64 arrays), each one that can be seen
     for certain: it is the extreme of the model in a direction u (no vertex lies farther along
     u, so nothing can hide it from a camera beyond it along u) and not on a boundary edge of
     the mesh. For each, the view's camera is put at v + d u looking at v (d small: the
     vertex's neighbours are tens of pixels away on screen), the page draws, the test projects
     v with the camera's matrices (window.rephotoView...viewProjection(), projected here) and
     compares the screenshot's pixel there with the jet colour of the vertex's error over the
     view's [low, high] range, computed here from the definition in src/rephoto/core/colormap.cc
     (each channel clamp(1.5 - |4t - c|, 0, 1), c = 3, 2, 1) and rounded to 8 bits; tolerance
     6 levels per channel. The three errors are chosen far apart (the lowest, a middle and the
     highest t among the candidates) so that the colours differ;
  3. clicking a camera frustum: the camera centre -R^T t of a photo camera (from the data
     block) is projected with the view's matrices after zooming out so the cameras are in
     view, a synthetic mouse click (Input.dispatchMouseEvent) is sent there, and the info
     panel must name that photo (.v3-selected data-name);
  4. with --note-visible (a comparison report): every cell of the ranking table's note
     column ends within the window's width (the papercut: it was off-screen at 1280 px).
Writes the screenshot of the whole view (default viewpoint, error colours) with --screenshot.
Exit code 0 when every check passed ("all checks passed"), 1 otherwise.
"""
import argparse
import base64
import json
import math
import os
import re
import struct
import sys
import time
import zlib

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from benchmark_pages import Browser  # noqa: E402


def decode_png(data):
    """8-bit RGB/RGBA non-interlaced PNG -> (width, height, channels, bytearray of rows)."""
    assert data[:8] == b"\x89PNG\r\n\x1a\n", "not a PNG"
    pos, idat, width = 8, b"", None
    while pos < len(data):
        length, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + length]
        if kind == b"IHDR":
            width, height, depth, colour, _, _, interlace = struct.unpack(">IIBBBBB", body)
            assert depth == 8 and colour in (2, 6) and interlace == 0, "unsupported PNG"
            channels = 3 if colour == 2 else 4
        elif kind == b"IDAT":
            idat += body
        pos += 12 + length
    raw = zlib.decompress(idat)
    stride = width * channels
    out = bytearray(height * stride)
    prev = bytearray(stride)
    for y in range(height):
        f = raw[y * (stride + 1)]
        line = bytearray(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
        for i in range(stride):
            a = line[i - channels] if i >= channels else 0
            b = prev[i]
            c = prev[i - channels] if i >= channels else 0
            if f == 1:
                line[i] = (line[i] + a) & 255
            elif f == 2:
                line[i] = (line[i] + b) & 255
            elif f == 3:
                line[i] = (line[i] + (a + b) // 2) & 255
            elif f == 4:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                pred = a if pa <= pb and pa <= pc else (b if pb <= pc else c)
                line[i] = (line[i] + pred) & 255
        out[y * stride:(y + 1) * stride] = line
        prev = line
    return width, height, channels, out


def jet(t):
    """src/rephoto/core/colormap.cc JetColor, as 8-bit RGB."""
    t = min(1.0, max(0.0, t))
    return [round(255 * min(1.0, max(0.0, 1.5 - abs(4 * t - c)))) for c in (3, 2, 1)]


def software_webgl_browser(chromium, width, height):
    """benchmark_pages.Browser with SwiftShader's WebGL, a fixed viewport and file:// access."""
    return Browser(chromium, flags=("--use-angle=swiftshader", "--enable-unsafe-swiftshader",
                                    "--hide-scrollbars", "--allow-file-access-from-files"),
                   width=width, height=height, timeout=120)


def view_data(html):
    """The first view's data block, parsed here from the HTML file."""
    m = re.search(r'<script type="application/json" class="v3-data">(.*?)</script>', html, re.S)
    if not m:
        raise RuntimeError("no 3D view data in the page")
    return json.loads(m.group(1))


def floats(b64):
    raw = base64.b64decode(b64)
    return struct.unpack(f"<{len(raw) // 4}f", raw)


def uints(b64):
    raw = base64.b64decode(b64)
    return struct.unpack(f"<{len(raw) // 4}I", raw)


def project(matrix, p, rect):
    """Column-major 4x4 `matrix` (projection * view) applied to p -> CSS pixel position."""
    x, y, z = p
    cx = matrix[0] * x + matrix[4] * y + matrix[8] * z + matrix[12]
    cy = matrix[1] * x + matrix[5] * y + matrix[9] * z + matrix[13]
    cz = matrix[2] * x + matrix[6] * y + matrix[10] * z + matrix[14]
    cw = matrix[3] * x + matrix[7] * y + matrix[11] * z + matrix[15]
    if cw <= 0:
        return None
    nx, ny, nz = cx / cw, cy / cw, cz / cw
    return (rect["left"] + (nx + 1) / 2 * rect["width"],
            rect["top"] + (1 - ny) / 2 * rect["height"], nz)


def choose_vertices(model):
    """Three surely visible vertices with far-apart errors (see the module comment)."""
    pos = floats(model["positions"])
    err = floats(model["error"])
    n = len(pos) // 3
    P = [(pos[3 * i], pos[3 * i + 1], pos[3 * i + 2]) for i in range(n)]
    boundary = set()
    if "indices" in model:
        idx = uints(model["indices"])
        edges = {}
        for f in range(0, len(idx), 3):
            for k in range(3):
                a, b = idx[f + k], idx[f + (k + 1) % 3]
                key = (min(a, b), max(a, b))
                edges[key] = edges.get(key, 0) + 1
        for (a, b), count in edges.items():
            if count == 1:
                boundary.update((a, b))
    lo = [min(p[k] for p in P) for k in range(3)]
    hi = [max(p[k] for p in P) for k in range(3)]
    extent = math.dist(lo, hi)
    low, high = model["low"], model["high"]
    # Directions: up (z) and tilted by 10 to 70 degrees towards 16 azimuths.
    directions = [(0.0, 0.0, 1.0)]
    for tilt in (10, 20, 30, 40, 50, 60, 70):
        for az in range(0, 360, 22):
            t, a = math.radians(tilt), math.radians(az)
            directions.append((math.sin(t) * math.cos(a), math.sin(t) * math.sin(a), math.cos(t)))
    candidates = {}
    for u in directions:
        dots = [p[0] * u[0] + p[1] * u[1] + p[2] * u[2] for p in P]
        top = max(dots)
        for i, d in enumerate(dots):
            if d >= top - 1e-6 * extent and i not in boundary and math.isfinite(err[i]):
                candidates.setdefault(i, u)
    if not candidates:
        raise RuntimeError("no candidate vertex")

    def t_of(i):
        return (err[i] - low) / (high - low) if high != low else 0.0

    ordered = sorted(candidates, key=lambda i: (t_of(i), i))
    picks = [ordered[0], ordered[len(ordered) // 2], ordered[-1]]
    # Distinct vertices, else what there is.
    seen, out = set(), []
    for i in picks:
        if i not in seen:
            seen.add(i)
            out.append(i)
    return [(i, P[i], candidates[i], err[i], t_of(i)) for i in out], extent


def load(browser, url):
    """Navigates to `url`; returns (seconds to the view's first frame, view state, timing)."""
    start = time.time()
    browser.call("Page.navigate", url=url)
    deadline = start + 120
    while True:
        state = browser.evaluate(
            "(function(){var v=document.querySelector('.view3d');"
            "return v ? (v.getAttribute('data-ready') || v.getAttribute('data-error') || '') : 'none';})()")
        if state not in ("", "none") or time.time() > deadline:
            break
        time.sleep(0.02)
    # One frame after the view started: the first drawing is on screen.
    browser.evaluate("new Promise(r => requestAnimationFrame(() => requestAnimationFrame(r)))")
    seconds = time.time() - start
    timing = browser.evaluate(
        "(function(){var n=performance.getEntriesByType('navigation')[0];"
        "return {dcl: n.domContentLoadedEventEnd, load: n.loadEventEnd};})()")
    return seconds, state, timing


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("report")
    ap.add_argument("--screenshot", help="PNG of the view as it opens (error colours)")
    ap.add_argument("--screenshot-selected", help="PNG of the view after the camera click")
    ap.add_argument("--width", type=int, default=1280)
    ap.add_argument("--height", type=int, default=900)
    ap.add_argument("--note-visible", action="store_true")
    ap.add_argument("--surface-click", action="store_true",
                    help="click a vertex and compare the listed views (models without occlusion)")
    ap.add_argument("--boxplot-labels", action="store_true",
                    help="check that every boxplot category label lies inside its plot")
    ap.add_argument("--min-checks", type=int, default=3)
    ap.add_argument("--model", help="label of the model to check (default: the first)")
    ap.add_argument("--loads", type=int, default=1,
                    help="load the page this many times (the first in a fresh browser) and "
                         "print each time and the median")
    args = ap.parse_args()
    chromium = os.environ.get("CHROMIUM", "/usr/bin/chromium")
    failures = []

    def check(condition, message):
        print(("ok   " if condition else "FAIL ") + message)
        if not condition:
            failures.append(message)

    html = open(args.report, encoding="utf-8").read()
    data = view_data(html)
    model_index = 0
    if args.model:
        labels = [m["label"] for m in data["models"]]
        if args.model not in labels:
            print(f"no model {args.model!r} (have {labels})")
            return 1
        model_index = labels.index(args.model)
    model = data["models"][model_index]
    for key in ("positions", "indices", "colors"):
        if key + "_of" in model:
            model[key] = data["models"][model[key + "_of"]][key]
    print(f"report {args.report}: {os.path.getsize(args.report) / 1e6:.1f} MB, "
          f"{len(data['models'])} model(s); model {model_index} '{model['label']}': {model['kind']}, "
          f"{model['vertices']} vertices, {model['faces']} faces "
          f"(of {model['original_faces']}), {len(model['cameras'])} cameras")
    browser = software_webgl_browser(chromium, args.width, args.height)
    try:
        url = "file://" + os.path.abspath(args.report)
        timings = []
        for attempt in range(args.loads):
            if attempt > 0:
                browser.call("Page.navigate", url="about:blank")
                time.sleep(0.2)
            seconds, state, timing = load(browser, url)
            timings.append(seconds)
            print(f"load {attempt + 1}: load+draw {seconds:.2f} s (navigation to the view's first frame; "
                  f"DOMContentLoaded {timing['dcl'] / 1000:.2f} s, load {timing['load'] / 1000:.2f} s "
                  f"in the page's clock)")
        check(state == "1", f"the 3D view started (state {state!r})")
        if state != "1":
            raise RuntimeError("no view")
        if args.loads > 1:
            print(f"load+draw median of {args.loads}: {sorted(timings)[len(timings) // 2]:.2f} s")
        view_id = browser.evaluate("document.querySelector('.view3d').id")
        js_view = f"window.rephotoView.views[{json.dumps(view_id)}]"
        browser.evaluate(f"document.getElementById({json.dumps(view_id)}).scrollIntoView()")
        if model_index:
            browser.evaluate(f"{js_view}.select({model_index})")
        browser.evaluate(f"{js_view}.render()")
        rect = browser.evaluate(
            f"(function(){{var r={js_view}.canvas.getBoundingClientRect();"
            "return {left:r.left, top:r.top, width:r.width, height:r.height};})()")
        if args.screenshot:
            shot = browser.call("Page.captureScreenshot", format="png", clip={
                "x": 0, "y": max(0, rect["top"] - 60) + browser.evaluate("window.scrollY"),
                "width": args.width, "height": rect["height"] + 130, "scale": 1})["data"]
            with open(args.screenshot, "wb") as f:
                f.write(base64.b64decode(shot))
            print(f"wrote {args.screenshot}")

        # 2. Colours at three vertices, each seen close up from beyond it along its direction
        # (in the error mode; a page may open in another).
        browser.evaluate(f"{js_view}.setMode('error')")
        picks, extent = choose_vertices(model)
        checked = 0
        for index, p, u, error, t in picks:
            d = 0.06 * extent
            eye = [p[k] + d * u[k] for k in range(3)]
            browser.evaluate(
                f"(function(){{var v={js_view}.view; v.camera.position.set({eye[0]},{eye[1]},{eye[2]});"
                f"v.controls.target.set({p[0]},{p[1]},{p[2]}); v.camera.near={d * 0.05};"
                f"v.camera.updateProjectionMatrix(); v.controls.update(); v.render();}})()")
            matrix = browser.evaluate(f"{js_view}.viewProjection()")
            rect = browser.evaluate(
                f"(function(){{var r={js_view}.canvas.getBoundingClientRect();"
                "return {left:r.left, top:r.top, width:r.width, height:r.height};})()")
            s = project(matrix, p, rect)
            if s is None:
                check(False, f"vertex {index} projects behind the camera")
                continue
            w, h, ch, pixels = decode_png(browser.screenshot())
            x, y = int(s[0]), int(s[1])
            got = list(pixels[(y * w + x) * ch:(y * w + x) * ch + 3])
            want = jet(t)
            ok = all(abs(a - b) <= 6 for a, b in zip(got, want))
            check(ok, f"vertex {index} at ({p[0]:.4g}, {p[1]:.4g}, {p[2]:.4g}), error {error:.5g} "
                      f"(t {t:.3f}): pixel ({x}, {y}) is {got}, jet gives {want}")
            checked += ok
        check(checked >= args.min_checks, f"{checked} vertex colours matched (need {args.min_checks})")

        # 2b. With --surface-click (a model nothing can hide a point of from any camera, such
        # as the fixture's plane): clicking the last vertex lists the views whose image it falls
        # in, in front of them (computed here from K, R, t).
        if args.surface_click and picks:
            index, p, u, error, t = picks[-1]
            s = project(matrix, p, rect)
            browser.call("Input.dispatchMouseEvent", type="mousePressed", x=s[0], y=s[1],
                         button="left", clickCount=1)
            browser.call("Input.dispatchMouseEvent", type="mouseReleased", x=s[0], y=s[1],
                         button="left", clickCount=1)
            listed = browser.evaluate(
                f"Array.from({js_view}.info.querySelectorAll('tbody tr td:first-child'))"
                ".map(function(td){return td.textContent;})")
            expected = []
            for c in model["cameras"] + data.get("suggested", []):
                R, T, K = c["R"], c["t"], c["K"]
                x = [sum(R[3 * r + k] * p[k] for k in range(3)) + T[r] for r in range(3)]
                if x[2] <= 0:
                    continue
                px, py = K[0] * x[0] / x[2] + K[2], K[1] * x[1] / x[2] + K[3]
                if 0 <= px < K[4] and 0 <= py < K[5]:
                    expected.append(c["name"])
            check(sorted(listed or []) == sorted(expected),
                  f"clicking the surface at vertex {index} lists {sorted(listed or [])}, "
                  f"expected {sorted(expected)}")

        # 3. Click a photo camera's frustum apex: from the view's own viewpoint, else from
        # farther back along it.
        target = None
        for zoom in (1.0, 2.2):
            browser.evaluate(f"(function(){{var v={js_view}.view; v.placeCamera();"
                             f"v.camera.position.sub(v.controls.target).multiplyScalar({zoom})"
                             ".add(v.controls.target); v.camera.near = v.extent * 0.005;"
                             "v.camera.updateProjectionMatrix(); v.controls.update(); v.render();})()")
            matrix = browser.evaluate(f"{js_view}.viewProjection()")
            rect = browser.evaluate(
                f"(function(){{var r={js_view}.canvas.getBoundingClientRect();"
                "return {left:r.left, top:r.top, width:r.width, height:r.height};})()")
            screen = []
            for c in model["cameras"] + data.get("suggested", []):
                R, t = c["R"], c["t"]
                centre = [-(R[0] * t[0] + R[3] * t[1] + R[6] * t[2]),
                          -(R[1] * t[0] + R[4] * t[1] + R[7] * t[2]),
                          -(R[2] * t[0] + R[5] * t[1] + R[8] * t[2])]
                s = project(matrix, centre, rect)
                if s and rect["left"] + 5 < s[0] < rect["left"] + rect["width"] - 5 and \
                        rect["top"] + 5 < s[1] < rect["top"] + rect["height"] - 5 and -1 < s[2] < 1:
                    screen.append((c["name"], s))
            for name, s in screen:
                if all(math.dist(s[:2], o[:2]) > 30 for n2, o in screen if n2 != name):
                    target = (name, s)
                    break
            if target:
                break
        check(target is not None, f"a camera centre in view, apart from the others "
                                  f"({len(screen)} in view)")
        if target:
            name, s = target
            for kind in ("mouseMoved", "mousePressed", "mouseReleased"):
                browser.call("Input.dispatchMouseEvent", type=kind, x=s[0], y=s[1],
                             button="left" if kind != "mouseMoved" else "none", clickCount=1)
            shown = browser.evaluate(
                f"(function(){{var e={js_view}.info.querySelector('.v3-selected');"
                "return e ? e.getAttribute('data-name') : null;})()")
            check(shown == name, f"clicking the frustum of {name} at ({s[0]:.0f}, {s[1]:.0f}) "
                                 f"shows {shown!r}")
            cam = next(c for c in model["cameras"] + data.get("suggested", []) if c["name"] == name)
            wanted = sum(1 for key in ("photo", "rephoto", "error_image") if key in cam)
            images = browser.evaluate(
                f"(function(){{return Array.from({js_view}.info.querySelectorAll('img'))"
                ".filter(function(i){return i.complete && i.naturalWidth > 0;}).length;})()")
            check(images == wanted, f"its panel shows {images} decoded images of the {wanted} "
                                    "the page has for it (photo, rephoto, error)")
            if args.screenshot_selected:
                rect = browser.evaluate(
                    f"(function(){{var r={js_view}.canvas.getBoundingClientRect();"
                    "return {left:r.left, top:r.top, width:r.width, height:r.height};})()")
                shot = browser.call("Page.captureScreenshot", format="png", clip={
                    "x": 0, "y": max(0, rect["top"] - 60) + browser.evaluate("window.scrollY"),
                    "width": args.width, "height": rect["height"] + 130, "scale": 1})["data"]
                with open(args.screenshot_selected, "wb") as f:
                    f.write(base64.b64decode(shot))
                print(f"wrote {args.screenshot_selected}")
        # 4. The note column within the window.
        if args.note_visible:
            overflow = browser.evaluate(
                "(function(){document.getElementById('ranking').scrollIntoView();"
                "var cells=document.querySelectorAll('#ranking-table td.note');"
                "var worst=0; cells.forEach(function(c){worst=Math.max(worst,c.getBoundingClientRect().right);});"
                "return {cells: cells.length, right: worst, width: window.innerWidth};})()")
            check(overflow["cells"] > 0 and overflow["right"] <= overflow["width"],
                  f"ranking notes end at {overflow['right']:.0f} px of {overflow['width']} "
                  f"({overflow['cells']} cells)")
        # 5. Boxplot category labels inside their SVG (the papercut: "Simplified (3 of ..." cut).
        if args.boxplot_labels:
            labels = browser.evaluate(
                "(function(){var out=[];document.querySelectorAll('svg.boxplot').forEach(function(svg){"
                "var vb=svg.viewBox.baseVal;svg.querySelectorAll('text.category').forEach(function(t){"
                "var b=t.getBBox(),m=t.getCTM(),p=svg.createSVGPoint(),xs=[],ys=[];"
                "[[b.x,b.y],[b.x+b.width,b.y],[b.x,b.y+b.height],[b.x+b.width,b.y+b.height]].forEach(function(c){"
                "p.x=c[0];p.y=c[1];var q=p.matrixTransform(m);xs.push(q.x);ys.push(q.y);});"
                "var s=svg.getScreenCTM().inverse();"
                "out.push({text:t.firstChild.textContent,"
                "inside: Math.min.apply(null,xs)>=-0.5 && Math.min.apply(null,ys)>=-0.5 &&"
                " Math.max.apply(null,xs)<=vb.width+0.5 && Math.max.apply(null,ys)<=vb.height+0.5});});});"
                "return out;})()")
            bad = [l["text"] for l in labels if not l["inside"]]
            check(labels and not bad, f"{len(labels)} boxplot labels inside their plots; outside: {bad}")
            cut = [l["text"] for l in labels if "\u2026" in l["text"]]
            check(not cut, f"no boxplot label shortened: {cut}")
        check(not browser.errors, "no console errors: " + "; ".join(browser.errors))
    finally:
        browser.close()
    if failures:
        print(f"{len(failures)} check(s) failed")
        return 1
    print("all checks passed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
