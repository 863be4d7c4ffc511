// The live page: one self-contained HTML document; its script polls /api/live once a second and
// redraws only when the state's "version" changed (no reload, no external resources).
#include <string>

#include "rephoto/live/live_server.h"

namespace rephoto::live {

const std::string& LivePageHtml() {
  static const std::string html = R"HTML(<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>rephoto live</title>
<meta name="viewport" content="width=device-width, initial-scale=1"><link rel="icon" href="data:,">
<style>
body{font-family:system-ui,sans-serif;margin:1em 2em;color:#222}
h1{font-size:1.4em} h2{font-size:1.1em;margin-top:1.4em}
table{border-collapse:collapse;font-size:.9em} td,th{padding:2px 8px;border-bottom:1px solid #ddd;text-align:left}
.status-registered{color:#080} .bad{color:#b00}
.row{display:flex;gap:1em;flex-wrap:wrap} figure{margin:0} figcaption{font-size:.85em;color:#555}
img{max-width:320px;border:1px solid #ccc;background:#eee}
code{font-size:.8em;word-break:break-all} .figure{font-size:1.3em;font-weight:600}
figure.suggestion{max-width:330px}
</style></head><body>
<h1>rephoto live <span id="version" style="font-size:.6em;color:#888"></span></h1>
<p id="summary">waiting for the first update…</p>
<h2>Prediction of each photo before it joined (arrival order)</h2>
<svg id="curve" width="720" height="220" role="img" aria-label="prediction error and completeness per photo"></svg>
<p style="font-size:.85em;color:#555"><span style="color:#c33">&#9632;</span> mean 1-NCC of the prediction (covered pixels)
&nbsp; <span style="color:#36c">&#9632;</span> completeness (share of the photo the earlier photos predict).
A good capture drives the error down; a low completeness means the photo saw something new.</p>
<section id="closed-loop" hidden><h2>Closed loop this run belongs to (<code>rephoto live-experiment</code>)</h2>
<img id="closed-loop-plot" alt="unseen surface and held-out prediction error per photo added: suggested, ring, random"
 style="max-width:720px;background:#fff">
</section>
<h2>Latest photo</h2>
<div class="row" id="latest"></div>
<h2>Next views</h2>
<p>Take these next (best first). Poses: <a href="/files/suggestions/transforms.json">transforms.json</a>,
COLMAP <a href="/files/suggestions/sparse/cameras.txt">cameras.txt</a> /
<a href="/files/suggestions/sparse/images.txt">images.txt</a>; each entry of
<a href="/api/live">/api/live</a> "suggestions" has the pose sidecar's shape.</p>
<div class="row" id="suggestions"></div>
<h2>Photos</h2>
<table id="photos"><thead><tr><th>#</th><th>photo</th><th>status</th><th>completeness</th><th>1-NCC</th><th>seconds (register / predict / depth / model / suggest)</th><th>message</th></tr></thead><tbody></tbody></table>
<script>
"use strict";
let shown = -1;
function el(tag, attrs, text) { const e = document.createElement(tag);
  for (const k in attrs || {}) e.setAttribute(k, attrs[k]); if (text !== undefined) e.textContent = text; return e; }
function fmt(v, d) { return (v === null || v === undefined) ? "–" : Number(v).toFixed(d); }
function pct(v) { return (v === null || v === undefined) ? "–" : (100 * v).toFixed(1) + " %"; }
function file(kind, name, v) { return "/files/" + kind + "/" + encodeURIComponent(name) + "?v=" + v; }
function drawCurve(photos) {
  const svg = document.getElementById("curve"); while (svg.firstChild) svg.removeChild(svg.firstChild);
  const reg = photos.filter(p => p.status === "registered");
  const W = 720, H = 220, L = 40, B = 24, T = 8, n = Math.max(reg.length, 2);
  const ns = "http://www.w3.org/2000/svg";
  const add = (tag, a) => { const e = document.createElementNS(ns, tag); for (const k in a) e.setAttribute(k, a[k]); svg.appendChild(e); return e; };
  add("rect", {x: L, y: T, width: W - L - 4, height: H - T - B, fill: "none", stroke: "#999"});
  for (const t of [0, 0.5, 1]) { const y = T + (1 - t) * (H - T - B);
    const lab = add("text", {x: 4, y: y + 4, "font-size": 10}); lab.textContent = t.toFixed(1); }
  const x = i => L + (W - L - 4) * (n === 1 ? 0 : i / (n - 1));
  const y = v => T + (1 - Math.max(0, Math.min(1, v))) * (H - T - B);
  for (const [key, colour] of [["error", "#c33"], ["completeness", "#36c"]]) {
    let d = "";
    reg.forEach((p, i) => { const v = p[key]; if (v === null || v === undefined) return;
      d += (d ? " L" : "M") + x(i).toFixed(1) + " " + y(v).toFixed(1);
      add("circle", {cx: x(i), cy: y(v), r: 2.5, fill: colour, "data-key": key}); });
    if (d) add("path", {d: d, fill: "none", stroke: colour, "stroke-width": 1.5, class: "curve-" + key});
  }
  const lab = add("text", {x: L, y: H - 6, "font-size": 10}); lab.textContent = "photo 1 … " + reg.length;
}
function render(s) {
  document.getElementById("version").textContent = "update " + s.version;
  const reg = s.photos.filter(p => p.status === "registered");
  const others = s.photos.length - reg.length;
  const m = s.model || {};
  document.getElementById("summary").innerHTML = "";
  const sum = document.getElementById("summary");
  sum.appendChild(el("span", {class: "figure", id: "registered-count"}, reg.length + " photos registered"));
  sum.appendChild(document.createTextNode(", " + others + " set aside, " + s.waiting + " waiting for a pose" +
    (s.waiting_reason ? " (" + s.waiting_reason + ")" : "") + ". Model: " +
    pct(m.observed_fraction) + " of its surface observed, " + pct(m.well_covered_fraction) +
    " well covered (seen by 2+ photos with projected 1-NCC <= " + (m.well_covered_threshold ?? "–") + ")."));
  drawCurve(s.photos);
  const latest = document.getElementById("latest"); latest.innerHTML = "";
  const lp = s.photos.find(p => p.name === s.latest);
  if (lp) {
    latest.appendChild(el("p", {id: "latest-name"}, lp.name + ": completeness " + pct(lp.completeness) + ", 1-NCC " + fmt(lp.error, 3)));
    const row = el("div", {class: "row"});
    for (const [kind, cap] of [["photo", "photo"], ["prediction", "predicted from the earlier photos"], ["error", "1-NCC error (blue 0, red 1)"]]) {
      if (kind !== "photo" && !lp.has_error_image) continue;
      const f = el("figure"); f.appendChild(el("img", {src: file(kind, lp.name, s.version), alt: cap, class: "latest-" + kind}));
      f.appendChild(el("figcaption", {}, cap)); row.appendChild(f);
    }
    latest.appendChild(row);
  }
  const sg = document.getElementById("suggestions"); sg.innerHTML = "";
  (s.suggestions || []).forEach((g, i) => {
    const f = el("figure", {class: "suggestion"});
    if (g.has_render) f.appendChild(el("img", {src: file("suggestion", g.name, s.version), alt: g.name}));
    f.appendChild(el("figcaption", {}, (i + 1) + ". " + g.how));
    f.appendChild(el("figcaption", {}, "newly sees " + pct(g.unseen_area_fraction) + " of the model (unseen so far)"));
    const c = el("code"); c.textContent = JSON.stringify({camera: g.camera, qvec: g.qvec.map(v => +v.toFixed(6)), tvec: g.tvec.map(v => +v.toFixed(6))});
    f.appendChild(c); sg.appendChild(f);
  });
  const tb = document.querySelector("#photos tbody"); tb.innerHTML = "";
  s.photos.forEach((p, i) => {
    const tr = el("tr", {"data-name": p.name, "data-status": p.status});
    const sec = p.seconds || {};
    const cells = [i + 1, p.name, p.status, pct(p.completeness), fmt(p.error, 3),
      ["register", "predict", "depth", "model", "suggest"].map(k => fmt(sec[k], 2)).join(" / "), p.message || ""];
    cells.forEach((c, k) => { const td = el("td", {}, String(c));
      if (k === 2) td.className = p.status === "registered" ? "status-registered" : "bad"; tr.appendChild(td); });
    tb.appendChild(tr);
  });
}
async function poll() {
  try {
    const r = await fetch("/api/live", {cache: "no-store"});
    if (r.ok) {
      const s = await r.json();
      // The closed-loop plot, when the run has one (set once; the section shows when it loaded).
      const plot = document.getElementById("closed-loop-plot");
      if (s.closed_loop_plot && !plot.getAttribute("src")) {
        plot.onload = () => { document.getElementById("closed-loop").hidden = false; };
        plot.src = "/files/closed_loop.svg";
      }
      if (s.version !== shown) { shown = s.version; render(s); }
    }
  } catch (e) { /* the server may be restarting: try again */ }
  setTimeout(poll, 1000);
}
poll();
</script></body></html>
)HTML";
  return html;
}

}  // namespace rephoto::live
