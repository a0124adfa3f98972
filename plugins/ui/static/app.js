// hapticdesk's page: live view, layout designer, strokes. Hand-written, no framework, no
// build step, nothing fetched but this server's own API. Desk coordinates are metres with
// y away from the person; the SVG draws millimetres with y flipped (SVG y points down).
// What a person reads (the touch's x and y, the set-up's points) is in the layout's units.
"use strict";

const NS = "http://www.w3.org/2000/svg";
const TOKEN = new URLSearchParams(location.search).get("token");
const TRAIL_S = 0.6;      // how long the trail behind the dot is
const FORCE_S = 5.0;      // the force plot's span
const MAX_LIST = 60;      // entries kept in the gesture, action and notice lists
const LINGER_S = 0.5;     // a lifted finger's dot fades out over this long (a tap is short)

const $ = (id) => document.getElementById(id);
const X = (x) => x * 1000;
const Y = (y) => -y * 1000;
const fromSvg = (px, py) => [px / 1000, -py / 1000];

let desk = null;          // the last `desk` message
let connected = false;    // the WebSocket is open
let schema = null;        // gesture and action option forms (GET /api/schema)
let tab = "live";
const trail = [];         // [t, x, y]
const forces = [];        // [t, force]
let lastT = null;
let lastTouch = null;     // {t, x, y, force, region}: the last located touch, for the fade

function api(path, options = {}) {
  const headers = Object.assign({}, options.headers || {});
  if (TOKEN) headers["Authorization"] = "Bearer " + TOKEN;
  return fetch(path, Object.assign({}, options, { headers }));
}

function el(name, attrs = {}, parent = null) {
  const node = document.createElementNS(NS, name);
  for (const [k, v] of Object.entries(attrs)) node.setAttribute(k, v);
  if (parent) parent.appendChild(node);
  return node;
}

function pointsAttr(outline) {
  return outline.map(([x, y]) => `${X(x).toFixed(1)},${Y(y).toFixed(1)}`).join(" ");
}

// --- drawing the desk ------------------------------------------------------------------------

// --- the layout's units ------------------------------------------------------------------------

const UNIT_METRES = { m: 1, cm: 0.01, mm: 0.001 };
const UNIT_DECIMALS = { m: 3, cm: 1, mm: 0 };
function units() { return (desk && UNIT_METRES[desk.units]) ? desk.units : "m"; }
function inUnits(metres, extra = 0) {  // a length as the layout writes it, e.g. "12.5 cm"
  return `${(metres / UNIT_METRES[units()]).toFixed(UNIT_DECIMALS[units()] + extra)} ${units()}`;
}
function toUnits(metres) {
  const f = 10 ** (UNIT_DECIMALS[units()] + 1);
  return Math.round(metres / UNIT_METRES[units()] * f) / f;
}
function toMetres(value) { return value * UNIT_METRES[units()]; }

// --- one status: connected, sensing, actions ---------------------------------------------------

function showStatus() {
  const box = $("status");
  if (!connected) { box.textContent = "disconnected: retrying…"; box.className = "status off"; }
  else if (desk && desk.live) { box.textContent = "live"; box.className = "status on"; }
  else {
    box.textContent = "not sensing: the source ended (the designer still works)";
    box.className = "status idle";
  }
  const hint = $("actions-hint");
  hint.classList.remove("off");
  if (!desk || !desk.live) hint.textContent = "nothing runs: no desk is sensing";
  else if (desk.actions === false) {
    hint.textContent = "Actions are off: this is a preview (hapticdesk ui without --actions). " +
      "Gestures are recognised and shown here; nothing is sent.";
    hint.classList.add("off");
  } else hint.textContent = actionRows.size ? "" : "no action has run yet";
}

function drawDesk(message) {
  desk = message;
  $("desk-name").textContent = `hapticdesk — ${message.name}`;
  for (const span of document.querySelectorAll(".units")) span.textContent = units();
  showStatus();
  const surfaces = $("surfaces"), sensors = $("sensors");
  surfaces.replaceChildren(); sensors.replaceChildren();
  let xs = [], ys = [];
  for (const s of message.surfaces) {
    const cls = s.horizontal ? "surface" : "surface side";
    if (!s.horizontal) continue;  // a vertical panel has no place on the plan view
    el("polygon", { class: cls, points: pointsAttr(s.polygon), "data-surface": s.name }, surfaces);
    for (const [x, y] of s.polygon) { xs.push(x); ys.push(y); }
  }
  for (const s of message.sensors) {
    el("circle", { class: "sensor", cx: X(s.x), cy: Y(s.y), r: 8 }, sensors);
    xs.push(s.x); ys.push(s.y);
  }
  if (xs.length) {
    const pad = 0.04;
    const x0 = Math.min(...xs) - pad, x1 = Math.max(...xs) + pad;
    const y0 = Math.min(...ys) - pad, y1 = Math.max(...ys) + pad;
    $("desk").setAttribute("viewBox", `${X(x0)} ${Y(y1)} ${X(x1 - x0)} ${X(y1 - y0)}`);
  }
  drawRegions();
  fillBindingForm();
  if (!message.regions.length && !$("events").children.length) {
    $("events-hint").textContent = "this layout has no regions yet: draw one in the Designer, " +
      "then bind a gesture to it";
  }
}

function drawRegions() {
  const g = $("regions");
  g.replaceChildren();
  for (const r of desk.regions) {
    const shape = r.kind === "circle"
      ? el("circle", { cx: X(r.center[0]), cy: Y(r.center[1]), r: X(r.radius) }, g)
      : el("polygon", { points: pointsAttr(r.outline) }, g);
    shape.setAttribute("class", "region");
    shape.setAttribute("data-region", r.name);
    shape.setAttribute("id", "region-" + r.name);
    const cx = r.outline.reduce((a, p) => a + p[0], 0) / r.outline.length;
    const cy = r.outline.reduce((a, p) => a + p[1], 0) / r.outline.length;
    const label = el("text", { x: X(cx), y: Y(cy), "text-anchor": "middle", class: "region-label" }, g);
    label.textContent = r.name;
  }
}

// point in region: exact for circles, even-odd rule for outlines
function regionAt(x, y, surface) {
  if (!desk || x === null) return null;
  let found = null;
  for (const r of desk.regions) {
    if (surface && r.surface !== surface) continue;
    let inside = false;
    if (r.kind === "circle") {
      inside = Math.hypot(x - r.center[0], y - r.center[1]) <= r.radius;
    } else {
      const p = r.outline;
      for (let i = 0, j = p.length - 1; i < p.length; j = i++) {
        if ((p[i][1] > y) !== (p[j][1] > y) &&
            x < ((p[j][0] - p[i][0]) * (y - p[i][1])) / (p[j][1] - p[i][1]) + p[i][0]) inside = !inside;
      }
    }
    if (inside) { found = r.name; break; }
  }
  return found;
}

// --- live view -------------------------------------------------------------------------------

const stats = (window.hapticdeskStats = { contacts: 0 });  // read by scripts/ui_cost.py

function onContact(m) {
  stats.contacts += 1;
  if (lastT !== null && m.t < lastT) { trail.length = 0; forces.length = 0; }  // a new run
  lastT = m.t;
  $("tare").textContent = (m.tared ? "" : "taring: keep the desk still ") +
    (m.paused ? "paused: gestures are not sent" : "");
  forces.push([m.t, m.force_n]);
  while (forces.length && forces[0][0] < m.t - FORCE_S) forces.shift();
  const touching = m.phase === "touch" || m.phase === "hold" || m.phase === "release";
  const located = m.x !== null && m.y !== null;
  if (touching && located) trail.push([m.t, m.x, m.y]);
  while (trail.length && (trail[0][0] < m.t - TRAIL_S)) trail.shift();
  if (!touching) trail.length = 0;
  const dot = $("touch");
  let region = touching && located ? regionAt(m.x, m.y, m.surface) : null;
  if (touching && located) {
    lastTouch = { t: m.t, x: m.x, y: m.y, force: m.force_n, region };
    if (region) $("last-region").textContent = region;
  }
  const shown = touching && located ? lastTouch
    : (lastTouch && m.t - lastTouch.t < LINGER_S ? lastTouch : null);
  if (shown) {
    dot.setAttribute("cx", X(shown.x)); dot.setAttribute("cy", Y(shown.y));
    dot.setAttribute("r", Math.min(60, 6 + 2.5 * shown.force));  // mm: sized by force
    dot.style.opacity = shown === lastTouch && !(touching && located) ? 0.4 : 0.85;
  } else {
    dot.setAttribute("r", 0);
  }
  $("trail").setAttribute("points", trail.map(([, x, y]) => `${X(x)},${Y(y)}`).join(" "));
  for (const node of document.querySelectorAll(".region.hot")) node.classList.remove("hot");
  const lit = region || (shown ? shown.region : null);
  if (lit) $("region-" + lit)?.classList.add("hot");
  $("touch-region").textContent = region || "—";
  $("rx").textContent = located ? inUnits(m.x) : "—";
  $("ry").textContent = located ? inUnits(m.y) : "—";
  $("rf").textContent = m.force_n.toFixed(1);
  $("rphase").textContent = m.phase || "—";
  if (recordingFromDesk) recordDeskSample(m, touching, located);
  setupContact(m);
  weightContact(m);
  drawForce(m.t);
}

// The force over the last FORCE_S seconds, drawn in the element's own pixels (so the labels
// are not stretched): a time axis in seconds before now, and newtons up the left.
const FORCE_PAD = { left: 36, right: 8, top: 8, bottom: 20 };
let forceAxes = "";       // the size and scale the axes were drawn for

function drawForce(now) {
  const svg = $("force");
  const w = svg.clientWidth || 500, h = svg.clientHeight || 100;
  const top = Math.max(20, Math.ceil(Math.max(0, ...forces.map((f) => f[1])) / 10) * 10);
  const x0 = FORCE_PAD.left, x1 = w - FORCE_PAD.right, y0 = FORCE_PAD.top, y1 = h - FORCE_PAD.bottom;
  const key = `${w}x${h}/${top}`;
  if (key !== forceAxes) {
    forceAxes = key;
    svg.setAttribute("viewBox", `0 0 ${w} ${h}`);
    const g = $("force-axes");
    g.replaceChildren();
    for (let s = 0; s <= FORCE_S; s += 1) {
      const x = x1 - (x1 - x0) * s / FORCE_S;
      el("line", { class: s === 0 ? "axis-line" : "grid-line", x1: x, y1: y0, x2: x, y2: y1 }, g);
      const anchor = s === 0 ? "end" : s === FORCE_S ? "start" : "middle";
      el("text", { class: "axis", x, y: h - 5, "text-anchor": anchor }, g)
        .textContent = s === 0 ? "now" : `−${s} s`;
    }
    for (const f of [0, top / 2, top]) {
      const y = y1 - (y1 - y0) * f / top;
      el("line", { class: f === 0 ? "axis-line" : "grid-line", x1: x0, y1: y, x2: x1, y2: y }, g);
      el("text", { class: "axis", x: x0 - 4, y: y + 4, "text-anchor": "end" }, g).textContent = `${f} N`;
    }
  }
  $("force-line").setAttribute("points", forces.map(([t, f]) =>
    `${(x1 - (x1 - x0) * (now - t) / FORCE_S).toFixed(1)},${(y1 - (y1 - y0) * f / top).toFixed(1)}`).join(" "));
}

function addItem(listId, text, cls) {
  const list = $(listId);
  const li = document.createElement("li");
  li.textContent = text;
  if (cls) li.className = cls;
  list.prepend(li);
  while (list.children.length > MAX_LIST) list.lastChild.remove();
  return li;
}

// A continuous gesture (slide, force) is one line from its begin to its end, its updates
// counted on it; a tap is a line of its own, so taps stay in view while a slider moves.
const going = new Map();  // gesture + region -> {li, first, value, updates, t}

function onGesture(m) {
  $("events-hint").textContent = "";
  const where = m.region ?? "anywhere";
  const key = `${m.gesture} ${where}`;
  if (m.phase === "begin" || m.phase === "update" || ((m.phase === "end" || m.phase === "cancel") && going.has(key))) {
    let g = going.get(key);
    if (!g || m.phase === "begin") {
      g = { li: addItem("events", "", "going"), first: m.value, updates: 0, t: m.t };
      going.set(key, g);
    }
    if (m.phase === "update") g.updates += 1;
    g.value = m.value;
    const values = m.value !== undefined && g.first !== undefined
      ? ` ${g.first.toFixed(2)} → ${m.value.toFixed(2)}` : "";
    const ended = m.phase === "end" || m.phase === "cancel";
    const state = ended ? ` ${m.phase}` : " …";
    const updates = g.updates ? ` (${g.updates} updates)` : "";
    g.li.textContent = `${g.t.toFixed(2)} s  ${m.gesture} ${where}${values}${updates}${state} → ${m.action}`;
    if (ended) { g.li.className = m.phase === "cancel" ? "failed" : ""; going.delete(key); }
    return;
  }
  const detail = m.shape ?? m.direction ?? m.level ?? (m.value !== undefined ? m.value.toFixed(2) : "");
  const phase = m.phase ? ` ${m.phase}` : "";
  addItem("events", `${m.t.toFixed(2)} s  ${m.gesture} ${where} ${detail ?? ""}${phase} → ${m.action}`);
}

const actionRows = new Map();
function onAction(m) {
  const text = `${m.label}: ${m.ok} done` + (m.failed ? `, ${m.failed} failed` : "") +
    (m.timed_out ? `, ${m.timed_out} timed out` : "") + (m.dropped ? `, ${m.dropped} dropped` : "");
  let li = actionRows.get(m.label);
  if (!li) { li = document.createElement("li"); actionRows.set(m.label, li); $("actions").prepend(li); }
  li.textContent = text;
  li.className = m.failed || m.timed_out || m.dropped ? "failed" : "";
  showStatus();
}

function onNotice(m) {
  addItem("notices", (m.t !== undefined ? `${m.t.toFixed(2)} s ` : "") + `${m.kind}: ${m.message}`,
    m.kind === "layout" ? "failed" : "");
}

function connect() {
  const proto = location.protocol === "https:" ? "wss" : "ws";
  const ws = new WebSocket(`${proto}://${location.host}/ws` + (TOKEN ? `?token=${TOKEN}` : ""));
  ws.onopen = () => { connected = true; showStatus(); };
  ws.onclose = () => {
    connected = false; showStatus();
    setTimeout(connect, 1000);
  };
  ws.onmessage = (e) => {
    const m = JSON.parse(e.data);
    if (m.type === "desk") drawDesk(m);
    else if (m.type === "contact") onContact(m);
    else if (m.type === "gesture") onGesture(m);
    else if (m.type === "action") onAction(m);
    else if (m.type === "notice") onNotice(m);
  };
}

// --- tabs ------------------------------------------------------------------------------------

for (const button of document.querySelectorAll(".tab")) {
  button.addEventListener("click", () => {
    tab = button.dataset.tab;
    for (const b of document.querySelectorAll(".tab")) b.classList.toggle("active", b === button);
    for (const p of document.querySelectorAll(".panel")) p.classList.toggle("hidden", p.id !== "panel-" + tab);
    if (tab === "designer" && !$("yaml").value) loadYaml();
  });
}

// --- designer --------------------------------------------------------------------------------

async function loadYaml() {
  const r = await api("api/layout");
  $("yaml").value = await r.text();
  showErrors([]);
}

function showErrors(errors, fieldId = "yaml", boxId = "yaml-error") {
  const field = $(fieldId), box = $(boxId);
  field.classList.toggle("invalid", errors.length > 0);
  box.textContent = errors.map((e) => `line ${e.line}, column ${e.column}: ${e.message}`).join("\n");
  if (errors.length && errors[0].line > 0 && field.tagName === "TEXTAREA") {
    const lines = field.value.split("\n");
    let offset = 0;
    for (let i = 0; i < errors[0].line - 1 && i < lines.length; i++) offset += lines[i].length + 1;
    offset += Math.max(0, errors[0].column - 1);
    field.setSelectionRange(offset, offset + 1);
  }
}

async function check() {
  const r = await api("api/check", { method: "POST", body: $("yaml").value });
  const result = await r.json();
  showErrors(result.errors);
  if (result.regions && desk) {  // draw the edited layout's regions, saved or not
    desk.regions = result.regions;
    drawRegions();
    fillRegionSelect(result.regions.map((r) => r.name));
  }
  return result;
}

let checkTimer = null;
$("yaml").addEventListener("input", () => {
  clearTimeout(checkTimer);
  checkTimer = setTimeout(check, 250);
});

async function edit(op) {
  $("save-status").textContent = "";
  const r = await api("api/edit", {
    method: "POST", headers: { "Content-Type": "application/json" },
    body: JSON.stringify(Object.assign({ text: $("yaml").value }, op)),
  });
  const result = await r.json();
  if (!result.ok) return result;
  $("yaml").value = result.text;
  await check();
  return result;
}

// an edit drawn on the desk: a refused one says why beside the tools (it had failed silently,
// the drawing gone and nothing said)
async function drawEdit(op) {
  const result = await edit(op);
  $("draw-error").textContent = result.ok ? "" : result.errors.map((e) => e.message).join("\n");
  return result;
}

$("save").addEventListener("click", async () => {
  const r = await api("api/layout", { method: "PUT", body: $("yaml").value });
  const result = await r.json();
  showErrors(result.errors || []);
  $("save-status").textContent = result.ok
    ? (result.reloaded ? "saved; the running desk uses it now" : "saved")
    : "not saved";
});

function tool() { return document.querySelector("input[name=tool]:checked").value; }

function svgPoint(event) {
  const svg = $("desk");
  const p = svg.createSVGPoint();
  p.x = event.clientX; p.y = event.clientY;
  const q = p.matrixTransform(svg.getScreenCTM().inverse());
  return fromSvg(q.x, q.y);
}

let drag = null;       // {kind, start, region?}
let polygon = [];      // corners of a polygon being drawn
let mouseStroke = null;

$("desk").addEventListener("mousedown", (e) => {
  const p = svgPoint(e);
  if (tab === "strokes") { mouseStroke = [p]; drawDraft("stroke", mouseStroke); return; }
  if (tab !== "designer") return;
  const t = tool();
  if (t === "rect" || t === "circle") drag = { kind: t, start: p, end: p };
  else if (t === "move") {
    const name = e.target.getAttribute && e.target.getAttribute("data-region");
    if (name) drag = { kind: "move", start: p, end: p, region: desk.regions.find((r) => r.name === name) };
  }
});

$("desk").addEventListener("mousemove", (e) => {
  const p = svgPoint(e);
  if (mouseStroke) { mouseStroke.push(p); drawDraft("stroke", mouseStroke); return; }
  if (!drag) return;
  drag.end = p;
  if (drag.kind === "rect") drawDraft("rect", [drag.start, p]);
  else if (drag.kind === "circle") drawDraft("circle", [drag.start, p]);
  else if (drag.kind === "move") {
    const dx = p[0] - drag.start[0], dy = p[1] - drag.start[1];
    drawDraft("polygon", drag.region.outline.map(([x, y]) => [x + dx, y + dy]));
  }
});

$("desk").addEventListener("mouseup", async () => {
  if (mouseStroke) { const s = mouseStroke; mouseStroke = null; if (s.length > 2) scoreStroke(s); return; }
  if (!drag) return;
  const d = drag; drag = null;
  $("drawing").replaceChildren();
  const name = $("region-name").value.trim();
  if (d.kind === "rect") {
    await drawEdit({ op: "set_region", name, shape: "rect", rect: [d.start[0], d.start[1], d.end[0], d.end[1]] });
  } else if (d.kind === "circle") {
    const radius = Math.hypot(d.end[0] - d.start[0], d.end[1] - d.start[1]);
    await drawEdit({ op: "set_region", name, shape: "circle", center: d.start, radius });
  } else if (d.kind === "move") {
    const dx = d.end[0] - d.start[0], dy = d.end[1] - d.start[1];
    if (Math.abs(dx) + Math.abs(dy) < 1e-4) return;
    const r = d.region;
    let op;
    if (r.kind === "circle") op = { shape: "circle", center: [r.center[0] + dx, r.center[1] + dy], radius: r.radius };
    else if (r.kind === "rect") {
      const xs = r.outline.map((p) => p[0]), ys = r.outline.map((p) => p[1]);
      op = { shape: "rect", rect: [Math.min(...xs) + dx, Math.min(...ys) + dy, Math.max(...xs) + dx, Math.max(...ys) + dy] };
    } else op = { shape: "polygon", points: r.outline.map(([x, y]) => [x + dx, y + dy]) };
    await drawEdit(Object.assign({ op: "set_region", name: r.name }, op));
  }
});

$("desk").addEventListener("click", (e) => {
  if (tab !== "designer" || tool() !== "polygon") return;
  polygon.push(svgPoint(e));
  drawDraft("polygon", polygon);
});

$("desk").addEventListener("dblclick", async () => {
  if (tab !== "designer" || tool() !== "polygon") return;
  // the double click's two clicks repeat the last corner (a click before it may too): a
  // corner within 1 mm of the one before is the same corner
  const pts = polygon.filter((p, i) => i === 0 || Math.hypot(p[0] - polygon[i - 1][0], p[1] - polygon[i - 1][1]) > 0.001);
  polygon = [];
  $("drawing").replaceChildren();
  if (pts.length >= 3) await drawEdit({ op: "set_region", name: $("region-name").value.trim(), shape: "polygon", points: pts });
});

function drawDraft(kind, pts) {
  const g = $("drawing");
  g.replaceChildren();
  if (kind === "rect") {
    const [a, b] = pts;
    el("rect", { class: "draft", x: X(Math.min(a[0], b[0])), y: Y(Math.max(a[1], b[1])),
      width: X(Math.abs(b[0] - a[0])), height: X(Math.abs(b[1] - a[1])) }, g);
  } else if (kind === "circle") {
    const [c, p] = pts;
    el("circle", { class: "draft", cx: X(c[0]), cy: Y(c[1]), r: X(Math.hypot(p[0] - c[0], p[1] - c[1])) }, g);
  } else {
    el(kind === "stroke" ? "polyline" : "polygon",
      { class: kind === "stroke" ? "draft stroke" : "draft", points: pointsAttr(pts), id: "draft" }, g);
  }
}

function fillRegionSelect(names) {
  const select = $("bind-region");
  const current = select.value;
  select.replaceChildren(new Option("(anywhere)", ""));
  for (const n of names) select.appendChild(new Option(n, n));
  if ([...select.options].some((o) => o.value === current)) select.value = current;
}

async function loadSchema() {
  const r = await api("api/schema");
  schema = await r.json();
  const gs = $("bind-gesture");
  gs.replaceChildren(...Object.keys(schema.gestures).map((g) => new Option(g, g)));
  gs.value = "tap";
  const as = $("bind-action");
  as.replaceChildren(...Object.keys(schema.actions).map((a) => new Option(a, a)));
  as.value = "log" in schema.actions ? "log" : as.options[0]?.value;
  gestureForm(); actionForm();
}

function fillBindingForm() {
  if (desk) fillRegionSelect(desk.regions.map((r) => r.name));
}

function field(parent, key, spec, prefix) {
  const label = document.createElement("label");
  label.textContent = key + " ";
  label.title = spec.help || "";
  let input;
  if (spec.choices && spec.choices.length) {
    input = document.createElement("select");
    input.appendChild(new Option("(default)", ""));
    for (const c of spec.choices) input.appendChild(new Option(String(c), String(c)));
  } else {
    input = document.createElement("input");
    input.placeholder = spec.default === null || spec.default === undefined ? "" : String(spec.default);
    input.size = 14;
  }
  input.id = `${prefix}-${key}`;
  input.dataset.key = key;
  input.dataset.kind = spec.kind || spec.type || "text";
  label.appendChild(input);
  parent.appendChild(label);
}

$("bind-gesture").addEventListener("change", gestureForm);
$("bind-action").addEventListener("change", actionForm);

function gestureForm() {
  const box = $("gesture-options");
  box.replaceChildren();
  const specs = schema.gestures[$("bind-gesture").value] || {};
  for (const [key, spec] of Object.entries(specs)) if (spec.role === "match") field(box, key, spec, "gopt");
}

function actionForm() {
  const box = $("action-options");
  box.replaceChildren();
  const action = schema.actions[$("bind-action").value];
  if (action && action.options) {
    for (const [key, spec] of Object.entries(action.options)) field(box, key, spec, "aopt");
  } else {
    field(box, "options", { kind: "yaml", help: "the action's options as JSON, e.g. {}", default: "{}" }, "aopt");
  }
}

function readValue(input) {
  const text = input.value.trim();
  if (text === "") return undefined;
  const kind = input.dataset.kind;
  if (kind === "names") return text.split(",").map((s) => s.trim()).filter(Boolean);
  if (kind === "yaml" || kind === "json" || kind === "mapping") return JSON.parse(text);
  if (["number", "seconds", "length", "fraction", "newtons", "degrees", "integer"].includes(kind)) {
    const n = Number(text);
    return Number.isFinite(n) ? n : text;  // the check reports a word where a number belongs
  }
  if (kind === "bool") return text === "true";
  return text;
}

$("bind-add").addEventListener("click", async () => {
  $("binding-error").textContent = "";
  for (const n of document.querySelectorAll("#binding-form .invalid")) n.classList.remove("invalid");
  const options = {};
  for (const input of $("gesture-options").querySelectorAll("input, select")) {
    const v = readValue(input);
    if (v !== undefined) options[input.dataset.key] = v;
  }
  let actionOptions = {};
  try {
    for (const input of $("action-options").querySelectorAll("input, select")) {
      const v = readValue(input);
      if (v === undefined) continue;
      if (input.dataset.key === "options") actionOptions = v; else actionOptions[input.dataset.key] = v;
    }
  } catch (err) {
    $("binding-error").textContent = "the action's options: " + err.message;
    return;
  }
  const before = $("yaml").value.split("\n").length;
  const result = await edit({ op: "add_binding", gesture: $("bind-gesture").value,
    region: $("bind-region").value || null, options, do: { [$("bind-action").value]: actionOptions } });
  if (!result.ok) { $("binding-error").textContent = result.errors.map((e) => e.message).join("\n"); return; }
  // an error in the lines the new binding added belongs to the form's fields: mark them there
  const errors = (await check()).errors;
  if (errors.length && errors[0].line >= before - 1) {
    $("binding-error").textContent = errors.map((e) => `line ${e.line}, column ${e.column}: ${e.message}`).join("\n");
    for (const input of document.querySelectorAll("#gesture-options input, #action-options input")) {
      if (input.value && errors[0].message.includes(input.dataset.key)) input.classList.add("invalid");
    }
  }
});

// --- strokes ---------------------------------------------------------------------------------

let recordingFromDesk = false;
let deskStroke = [];
let lastStroke = null;

$("record-desk").addEventListener("click", () => {
  recordingFromDesk = true; deskStroke = [];
  $("record-status").textContent = "draw on the desk now…";
});

function recordDeskSample(m, touching, located) {
  if (touching && located) deskStroke.push([m.x, m.y]);
  else if (!touching && deskStroke.length > 2) {
    recordingFromDesk = false;
    $("record-status").textContent = `recorded ${deskStroke.length} points`;
    drawDraft("stroke", deskStroke);
    scoreStroke(deskStroke);
  }
}

async function scoreStroke(points) {
  lastStroke = points;
  $("stroke-error").textContent = "";
  const r = await api("api/strokes", { method: "POST", headers: { "Content-Type": "application/json" },
    body: JSON.stringify({ points }) });
  const result = await r.json();
  if (!result.ok) { $("stroke-error").textContent = result.errors.map((e) => e.message).join("\n"); return; }
  $("stroke-result").textContent = result.shape
    ? `recognised: ${result.shape} (score ${result.score.toFixed(3)})`
    : `not recognised (nearest ${result.best_shape}, ${result.score.toFixed(3)} < ${result.min_score})`;
  $("stroke-result").dataset.shape = result.shape || "";
  $("stroke-scores").replaceChildren(...result.scores.slice(0, 8).map((s) => {
    const li = document.createElement("li"); li.textContent = `${s.shape} ${s.score.toFixed(3)}`; return li;
  }));
}

$("stroke-keep").addEventListener("click", async () => {
  if (!lastStroke) return;
  $("yaml").value || await loadYaml();
  const result = await edit({ op: "add_template", shape: $("stroke-name").value.trim(), points: lastStroke });
  if (!result.ok) { $("stroke-error").textContent = result.errors.map((e) => e.message).join("\n"); return; }
  const r = await api("api/layout", { method: "PUT", body: $("yaml").value });
  const saved = await r.json();
  if (!saved.ok) { $("stroke-error").textContent = saved.errors.map((e) => `line ${e.line}, column ${e.column}: ${e.message}`).join("\n"); return; }
  $("record-status").textContent = `kept as ${$("stroke-name").value.trim()}`;
  await scoreStroke(lastStroke);
});

$("stroke-discard").addEventListener("click", () => {
  lastStroke = null; $("drawing").replaceChildren();
  $("stroke-result").textContent = ""; $("stroke-scores").replaceChildren();
});

// --- set-up check ----------------------------------------------------------------------------

let setupPresses = null;  // presses counted since Start (a release ends one)
let setupTouching = false;

// the marked points, in the layout's units (the set-up API takes metres)
function defaultPoints() {
  const xs = desk.outline.map((p) => p[0]), ys = desk.outline.map((p) => p[1]);
  const cx = (Math.min(...xs) + Math.max(...xs)) / 2, cy = (Math.min(...ys) + Math.max(...ys)) / 2;
  const hx = (Math.max(...xs) - Math.min(...xs)) / 3, hy = (Math.max(...ys) - Math.min(...ys)) / 3;
  return [[cx - hx, cy - hy], [cx + hx, cy - hy], [cx + hx, cy + hy], [cx - hx, cy + hy],
    [cx, cy], [cx + hx / 2, cy - hy / 3]].map(([x, y]) => [toUnits(x), toUnits(y)]);
}

function setupPoints() {  // metres
  try {
    const points = JSON.parse($("setup-points").value);
    return points.map(([x, y]) => [toMetres(x), toMetres(y)]);
  } catch { return null; }
}

function drawMarks(points, measured = null) {
  const g = $("marks");
  g.replaceChildren();
  if (!points) return;
  points.forEach(([x, y], k) => {
    el("line", { class: "mark", x1: X(x) - 12, y1: Y(y), x2: X(x) + 12, y2: Y(y) }, g);
    el("line", { class: "mark", x1: X(x), y1: Y(y) - 12, x2: X(x), y2: Y(y) + 12 }, g);
    el("text", { class: "mark-label", x: X(x) + 10, y: Y(y) - 10 }, g).textContent = String(k + 1);
    if (measured && measured[k]) {
      el("circle", { class: "measured", cx: X(measured[k][0]), cy: Y(measured[k][1]), r: 8 }, g);
    }
  });
}

$("setup-points").addEventListener("input", () => drawMarks(setupPoints()));

for (const button of document.querySelectorAll(".tab")) {
  button.addEventListener("click", () => {
    if (button.dataset.tab === "setup" && desk && !$("setup-points").value) {
      $("setup-points").value = JSON.stringify(defaultPoints());
    }
    drawMarks(button.dataset.tab === "setup" ? setupPoints() : null);
  });
}

function setupContact(m) {
  if (setupPresses === null) return;
  const touching = m.phase === "touch" || m.phase === "hold";
  const released = setupTouching && !touching;
  setupTouching = touching;
  if (!released) return;
  setupPresses += 1;
  const n = (setupPoints() || []).length;
  $("setup-status").textContent = setupPresses < n
    ? `press point ${setupPresses + 1} of ${n}` : "all points pressed: Finish";
}

$("setup-start").addEventListener("click", async () => {
  $("setup-error").textContent = "";
  const points = setupPoints();
  if (!points) { $("setup-error").textContent = "the points are not valid JSON"; return; }
  const r = await api("api/setup/start", { method: "POST", headers: { "Content-Type": "application/json" },
    body: JSON.stringify({ points }) });
  const result = await r.json();
  if (!result.ok) { $("setup-error").textContent = result.errors.map((e) => e.message).join("\n"); return; }
  setupPresses = 0; setupTouching = false;
  $("setup-status").textContent = "keep the desk quiet for 2 s, then press point 1";
});

$("setup-finish").addEventListener("click", async () => {
  setupPresses = null;
  $("setup-status").textContent = "checking…";
  const r = await api("api/setup/finish", { method: "POST" });
  const result = await r.json();
  if (!result.ok) {
    $("setup-status").textContent = "";
    $("setup-error").textContent = result.errors.map((e) => e.message).join("\n"); return;
  }
  $("setup-status").textContent = `checked ${result.captured_s} s`;
  $("setup-findings").replaceChildren(...(result.findings.length ? result.findings : [{ message: "nothing wrong found" }])
    .map((f) => { const li = document.createElement("li"); li.textContent = f.message; return li; }));
  $("setup-residuals").replaceChildren(...result.residual_m.map((d) => {
    const li = document.createElement("li");
    li.textContent = d === null ? "not located" : `placed ${inUnits(d, 1)} from the mark`;
    return li;
  }));
  $("setup-desk").textContent = `noise of Fz: ${result.noise_fz_n ?? "— (" + result.noise_reason + ")"} N; ` +
    `natural frequency: ${result.natural_frequency_hz ?? "— (" + result.frequency_reason + ")"} Hz`;
  $("setup-snippet").textContent = result.profile_snippet || "";
  drawMarks(result.points, result.measured.map((p, k) => (result.placed[k] ? p : null)));
});

// --- set-up with a known weight (load cells) ---------------------------------------------------
// Spots and cells in cm, the check in mm, whatever the layout's units: they are marked and
// measured with a ruler, and a check of a few millimetres read in metres says nothing.

let weightSpots = null;   // the spots shown (metres), in the order the weight goes on them
let weightPlaced = null;  // weights put down since Start (a touch beginning), or null
let weightTouching = false;
const cm = (metres) => `${(metres * 100).toFixed(1)} cm`;
const mm = (metres) => `${(metres * 1000).toFixed(1)} mm`;
const errorText = (result) => result.errors.map((e) => e.message).join("\n");

async function weightApi(path, options = {}) {
  const r = await api(path, options);
  try { return await r.json(); } catch {
    return { ok: false, errors: [{ message: `the desk answered ${r.status} ${r.statusText}` }] };
  }
}

function showWeightSpots(spots, located = null) {
  weightSpots = spots;
  $("weight-spots").replaceChildren(...spots.map(([x, y]) => {
    const li = document.createElement("li"); li.textContent = `x ${cm(x)}, y ${cm(y)}`; return li;
  }));
  drawMarks(spots, located);
}

function clearWeightResult() {
  for (const id of ["weight-error", "weight-check", "weight-profile"]) $(id).textContent = "";
  $("weight-cells").replaceChildren();
  $("weight-mass").classList.remove("invalid"); $("weight-count").classList.remove("invalid");
}

function weightError(result) {
  const message = errorText(result);
  $("weight-error").textContent = message;
  if (message.includes("mass_kg")) $("weight-mass").classList.add("invalid");
  if (message.includes("`count`")) $("weight-count").classList.add("invalid");
}

function massValue() {  // a number when it is one; else the text, for the desk to name
  const text = $("weight-mass").value.trim().replace(",", ".");
  const n = Number(text);
  return text !== "" && Number.isFinite(n) ? n : text;
}

$("weight-show").addEventListener("click", async () => {
  clearWeightResult();
  const result = await weightApi("api/setup/weight/spots?count=" + encodeURIComponent($("weight-count").value));
  if (!result.ok) { weightError(result); return; }
  showWeightSpots(result.spots_m);
});

$("weight-start").addEventListener("click", async () => {
  clearWeightResult();
  const result = await weightApi("api/setup/weight/start", { method: "POST",
    headers: { "Content-Type": "application/json" },
    body: JSON.stringify({ mass_kg: massValue(), count: Number($("weight-count").value) }) });
  if (!result.ok) { weightPlaced = null; $("weight-status").textContent = ""; weightError(result); return; }
  showWeightSpots(result.spots_m);
  weightPlaced = 0; weightTouching = false;
  $("weight-status").textContent =
    `desk empty; put the ${result.mass_kg} kg weight on spot 1 of ${result.spots_m.length}`;
});

// what the person is at, from the live view (the fit reads the raw readings, not this)
function weightContact(m) {
  if (weightPlaced === null || !weightSpots) return;
  const touching = m.phase === "touch" || m.phase === "hold";
  const put = touching && !weightTouching;
  weightTouching = touching;
  if (!put) return;
  weightPlaced += 1;
  const n = weightSpots.length;
  $("weight-status").textContent = weightPlaced < n
    ? `spot ${weightPlaced}: still for 2 s, lift it off, then spot ${weightPlaced + 1} of ${n}`
    : `spot ${n}: still for 2 s, lift it off, then Finish`;
}

$("weight-finish").addEventListener("click", async () => {
  weightPlaced = null;
  clearWeightResult();
  $("weight-status").textContent = "fitting…";
  const result = await weightApi("api/setup/weight/finish", { method: "POST" });
  if (!result.ok) { $("weight-status").textContent = ""; weightError(result); return; }
  $("weight-status").textContent = `read ${result.captured_s} s, fitted on ${result.spots_used} spots`;
  const loo = result.leave_one_out.map((c) => c.error_m).filter((e) => e !== null);
  const check = $("weight-check");
  if (result.check) {
    const before = result.check_before_m === null ? "" : ` (${mm(result.check_before_m)} with the profile as it was)`;
    check.textContent = `check spot ${result.check_index + 1}, not in the fit: placed ` +
      `${mm(result.check.error_m)} from its mark${before}: ` +
      (result.passed ? "good" : `more than ${mm(result.tolerance_m)}, do the set-up again`);
  } else {
    check.textContent = `${result.spots_m.length} spots: none left to check the fit on (use 4 or 5); ` +
      `each spot left out in turn was placed within ${loo.length ? mm(Math.max(...loo)) : "—"}`;
  }
  check.className = result.passed ? "" : "failed";
  const head = document.createElement("tr");
  for (const text of ["cell", "gain", "x", "y", "moved"]) {
    const th = document.createElement("th"); th.textContent = text; head.appendChild(th);
  }
  $("weight-cells").replaceChildren(head, ...result.cells.map((c) => {
    const tr = document.createElement("tr");
    const moved = Math.hypot(c.position_m[0] - c.profile_position_m[0], c.position_m[1] - c.profile_position_m[1]);
    const percent = ((c.gain - 1) * 100).toFixed(1);  // the gain against the profile's
    const gain = `${Number(percent) < 0 ? "−" : "+"}${percent.replace("-", "")} %`;
    for (const text of [c.channel, gain, cm(c.position_m[0]), cm(c.position_m[1]), mm(moved)]) {
      const td = document.createElement("td"); td.textContent = text; tr.appendChild(td);
    }
    return tr;
  }));
  $("weight-profile").textContent = result.profile_path
    ? `wrote ${result.profile_path}: use it with --desk ${result.profile_path} (or desk: in the layout)`
    : result.note;
  showWeightSpots(result.spots_m,
    result.leave_one_out.map((c) => (c.located_m.includes(null) ? null : c.located_m)));
});

connect();
loadSchema();
