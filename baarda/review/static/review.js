// baarda review: the page over the JSON API (docs/review.md).  Every text from the data is
// set with textContent, never parsed as HTML.
"use strict";
const TOKEN = new URLSearchParams(location.search).get("token") || "";
const SVGNS = "http://www.w3.org/2000/svg";
const state = { rows: [], sel: null, chipUrls: [], chipRound: 0 };
const $ = (id) => document.getElementById(id);

async function api(path, body) {
  const opts = { headers: { "X-Baarda-Token": TOKEN } };
  if (body !== undefined) {
    opts.method = "POST";
    opts.headers["Content-Type"] = "application/json";
    opts.body = JSON.stringify(body);
  }
  const r = await fetch(path, opts);
  if (!r.ok) {
    let msg = r.status + " " + r.statusText;
    try { msg = (await r.json()).error || msg; } catch (e) { /* not JSON */ }
    const err = new Error(msg);
    err.status = r.status;
    throw err;
  }
  return r;
}

function say(text) { $("message").textContent = text; }
function fmt(v, d) { return v === null || v === undefined ? "–" : Number(v).toFixed(d); }
function el(tag, text, cls) {
  const e = document.createElement(tag);
  if (text !== undefined) e.textContent = text;
  if (cls) e.className = cls;
  return e;
}

function showSummary(s) {
  $("name").textContent = s.name;
  const dl = $("summary");
  dl.replaceChildren();
  const g = s.global_test;
  const items = [
    ["sigma0", fmt(s.sigma0, 4)], ["redundancy", String(s.redundancy)],
    ["global test", g ? (g.accepted ? "accepted" : "rejected") + " (" + fmt(g.statistic, 3) +
      " vs " + fmt(g.critical, 3) + ")" : "–"],
    ["critical |w|", fmt(s.k_w, 2)], ["rejected", String(s.rejected)],
    ["significant", String(s.significant)], ["suspect", String(s.suspect)],
    ["inseparable", String(s.inseparable)], ["edits", String(s.edits)],
    ["last step", fmt(s.seconds, 2) + " s"],
  ];
  for (const [k, v] of items) {
    const d = el("div");
    d.append(el("dt", k), el("dd", v));
    d.dataset.key = k;
    dl.append(d);
  }
}

const keyOf = (r) => [r.kind, r.photo, r.point, r.component].join("\u0000");

// rows drawn at most: the worst first; the filters reach the others (2,000 rows took
// Chromium seconds to draw on a shared machine)
const MAX_ROWS = 500;

function filtered() {
  const v = $("f-verdict").value, k = $("f-kind").value;
  const ph = $("f-photo").value.trim(), pt = $("f-point").value.trim();
  return state.rows.filter((r) =>
    (!v || (v === "inseparable" ? r.rho_partner !== null : r.verdict === v)) &&
    (!k || r.kind === k) && (!ph || r.photo.includes(ph)) && (!pt || r.point.includes(pt)));
}

function showRows() {
  const tb = document.querySelector("#obs tbody");
  tb.replaceChildren();
  const rows = filtered().slice(0, MAX_ROWS);
  const sel = state.sel ? keyOf(state.sel) : null;
  for (const r of rows) {
    const tr = el("tr", undefined, "v-" + r.verdict);
    const p = r.rho_partner;
    const cells = [r.kind, r.photo, r.point, r.component, fmt(r.w, 2),
      r.mdb === null ? "–" : fmt(r.mdb, r.unit === "m" ? 3 : 1) + " " + r.unit,
      fmt(r.redundancy, 3), r.verdict,
      p ? [p.photo, p.point, p.component].filter(Boolean).join(" ") + " (" + fmt(r.rho_max, 3) + ")" : ""];
    cells.forEach((c, i) => tr.append(el("td", c, i >= 4 && i <= 6 ? "num" : "")));
    if (keyOf(r) === sel) tr.classList.add("sel");
    tr.addEventListener("click", () => select(r));
    tb.append(tr);
  }
  $("count").textContent = rows.length + " of " + state.rows.length + " shown";
}

async function loadRows() {
  const status = $("f-status").value;
  const data = await (await api("/api/observations?status=" + status)).json();
  state.rows = data.observations;
  if (state.sel) {
    const k = keyOf(state.sel);
    state.sel = state.rows.find((r) => keyOf(r) === k) || state.sel;
  }
  showRows();
}

function buttons() {
  const r = state.sel, img = r && r.kind === "image";
  $("b-reject").disabled = !img || r.verdict === "rejected";
  $("b-restore").disabled = !img || r.verdict !== "rejected";
  $("b-aside").disabled = !img;
  $("b-remeasure").disabled = !img;
}

async function select(r) {
  state.sel = r;
  showRows();
  buttons();
  $("selected").textContent = r.kind + " " + r.component + " of point " + r.point +
    (r.photo ? " on photo " + r.photo : "") + ": w " + fmt(r.w, 2) + ", " + r.verdict;
  await showChips(r);
}

async function showChips(r) {
  const box = $("chips");
  const round = ++state.chipRound;  // a later selection replaces this one's chips
  for (const u of state.chipUrls) URL.revokeObjectURL(u);
  state.chipUrls = [];
  box.replaceChildren();
  if (!r.point) return;
  let rays;
  try {
    rays = (await (await api("/api/rays?point=" + encodeURIComponent(r.point))).json()).rays;
  } catch (e) { say(e.message); return; }
  if (round !== state.chipRound) return;
  drawMap(r.point, rays);
  for (const ray of rays) {
    if (round !== state.chipRound) return;
    const fig = el("figure", undefined, ray.photo === r.photo ? "this" : "");
    fig.dataset.photo = ray.photo;
    const cap = el("figcaption", "photo " + ray.photo + ": w x " + fmt(ray.wx, 2) +
      ", y " + fmt(ray.wy, 2) + (ray.active_x && ray.active_y ? "" : " (rejected)"));
    box.append(fig);
    if (!ray.image) {
      fig.append(frame(ray));
      cap.textContent += " – no image: residual vector in the image frame (x1000)";
      fig.append(cap);
      continue;
    }
    try {
      const resp = await api("/api/chip?photo=" + encodeURIComponent(ray.photo) +
        "&point=" + encodeURIComponent(r.point));
      const url = URL.createObjectURL(await resp.blob());
      state.chipUrls.push(url);
      const img = el("img");
      img.src = url;
      img.alt = "image of point " + r.point + " on photo " + ray.photo;
      const scale = Number(resp.headers.get("X-Chip-Mm-Per-Px"));
      const scaleY = Number(resp.headers.get("X-Chip-Mm-Per-Px-Y") || scale);
      const [cx, cy] = (resp.headers.get("X-Chip-Centre") || "0,0").split(",").map(Number);
      img.addEventListener("click", (ev) => {
        const k = img.naturalWidth / img.clientWidth;
        const u = ev.offsetX * k - cx, v = ev.offsetY * k - cy;
        remeasureAt(ray, ray.x + u * scale, ray.y - v * scaleY);
      });
      fig.append(img);
    } catch (e) {
      fig.append(frame(ray));
      cap.textContent += " – " + e.message + "; residual vector in the image frame (x1000)";
    }
    fig.append(cap);
  }
}

function frame(ray) {
  // the photo's frame with the measured position and the residual vector (x 1000)
  const s = document.createElementNS(SVGNS, "svg");
  const h = Math.max(115, Math.abs(ray.x), Math.abs(ray.y)) * 1.1;
  s.setAttribute("viewBox", [-h, -h, 2 * h, 2 * h].join(" "));
  s.setAttribute("role", "img");
  const add = (tag, attrs) => {
    const e = document.createElementNS(SVGNS, tag);
    for (const [k, v] of Object.entries(attrs)) e.setAttribute(k, String(v));
    s.append(e);
    return e;
  };
  add("rect", { x: -h / 1.1, y: -h / 1.1, width: 2 * h / 1.1, height: 2 * h / 1.1,
    fill: "#f4f4f4", stroke: "#999", "stroke-width": h / 150 });
  const x = ray.x, y = -ray.y;
  add("circle", { cx: x, cy: y, r: h / 60, fill: "#080" });
  add("line", { x1: x, y1: y, x2: x + (ray.vx || 0) * 1000, y2: y - (ray.vy || 0) * 1000,
    stroke: "#c00", "stroke-width": h / 100 });
  return s;
}

function drawMap(point, rays) {
  // the projection centres in plan, the photos of the point highlighted, the point in red
  const m = state.map, box = $("map");
  box.replaceChildren();
  if (!m || !m.photos.length) return;
  const p = point ? m.points.find((q) => q[0] === point) : null;
  const xs = m.photos.map((q) => q[1]).concat(p ? [p[1]] : []);
  const ys = m.photos.map((q) => q[2]).concat(p ? [p[2]] : []);
  let x0 = Math.min(...xs), x1 = Math.max(...xs), y0 = Math.min(...ys), y1 = Math.max(...ys);
  const pad = Math.max(x1 - x0, y1 - y0, 1) * 0.05;
  x0 -= pad; x1 += pad; y0 -= pad; y1 += pad;
  const s = document.createElementNS(SVGNS, "svg");
  s.setAttribute("viewBox", [x0, -y1, x1 - x0, y1 - y0].join(" "));
  s.setAttribute("role", "img");
  const r = Math.max(x1 - x0, y1 - y0) / 150;
  const seen = new Set((rays || []).map((q) => q.photo));
  const dot = (x, y, rad, fill) => {
    const c = document.createElementNS(SVGNS, "circle");
    for (const [k, v] of Object.entries({ cx: x, cy: -y, r: rad, fill })) c.setAttribute(k, String(v));
    s.append(c);
    return c;
  };
  for (const [id, x, y] of m.photos) {
    const c = dot(x, y, seen.has(id) ? 1.6 * r : r, seen.has(id) ? "#2a5bd7" : "#999");
    const t = document.createElementNS(SVGNS, "title");
    t.textContent = "photo " + id;
    c.append(t);
  }
  if (p) dot(p[1], p[2], 2 * r, "#d22").classList.add("point");
  box.append(s);
}

function remeasureAt(ray, x, y) {
  if (!state.sel || ray.photo !== state.sel.photo) {
    say("click on the chip of photo " + (state.sel ? state.sel.photo : "?") + " to re-measure it");
    return;
  }
  $("r-x").value = x.toFixed(4);
  $("r-y").value = y.toFixed(4);
  say("new position " + x.toFixed(4) + ", " + y.toFixed(4) + " mm: press re-measure");
}

async function edit(action) {
  const r = state.sel || {};
  const body = { action, photo: r.photo || "", point: r.point || "", component: r.component || "" };
  if (action === "remeasure") {
    body.x_mm = parseFloat($("r-x").value);
    body.y_mm = parseFloat($("r-y").value);
    if (!isFinite(body.x_mm) || !isFinite(body.y_mm)) { say("type x and y (mm)"); return; }
  }
  say(action + " …");
  try {
    const t0 = performance.now();
    const a = await (await api("/api/edits", body)).json();
    showSummary(a.summary);
    const ch = $("changed");
    ch.replaceChildren(el("span", a.changed.length + " verdict(s) changed: "));
    for (const c of a.changed.slice(0, 30)) {
      ch.append(el("span", [c.photo, c.point, c.component].filter(Boolean).join(" ") + " " +
        c.before + "→" + c.after + "; "));
    }
    await loadRows();
    if (state.sel) await select(state.sel);
    say(action + ": sigma0 " + fmt(a.summary.sigma0, 4) + " (" +
      ((performance.now() - t0) / 1000).toFixed(2) + " s)");
  } catch (e) { say(action + " refused: " + e.message); }
}

async function save() {
  say("saving …");
  try {
    const a = await (await api("/api/save", {})).json();
    say("saved " + a.edits + " edit(s) to " + a.out);
  } catch (e) { say("save failed: " + e.message); }
}

async function start() {
  for (const [id, a] of [["b-reject", "reject"], ["b-restore", "restore"], ["b-aside", "aside"],
    ["b-remeasure", "remeasure"], ["b-undo", "undo"]]) {
    $(id).addEventListener("click", () => edit(a));
  }
  $("b-save").addEventListener("click", save);
  $("f-status").addEventListener("change", () => loadRows().catch((e) => say(e.message)));
  for (const id of ["f-verdict", "f-kind", "f-photo", "f-point"]) {
    $(id).addEventListener("input", showRows);
  }
  $("filters").addEventListener("submit", (ev) => ev.preventDefault());
  try {
    showSummary(await (await api("/api/summary")).json());
    await loadRows();
    state.map = await (await api("/api/map")).json();
    drawMap(null, []);
    say("");
  } catch (e) { say(e.message); }
}
document.addEventListener("DOMContentLoaded", start);
