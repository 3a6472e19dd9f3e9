// cvmeasure operator app: state from /api/events (Server-Sent Events), commands to /api.
// No build step, no framework: the server holds the state; this file only draws it.
"use strict";
const S = Object.assign({}, window.INITIAL_STATE || {});
const page = document.body.dataset.page;
const $ = (id) => document.getElementById(id);
const fmt = (v, d = 2) => (v === null || v === undefined ? "–" : Number(v).toFixed(d));
const esc = (t) => String(t).replace(/[&<>"]/g, (c) => ({ "&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;" })[c]);

function say(text, error) {
  const m = $("msg");
  if (!text) { m.hidden = true; return; }
  m.textContent = text; m.hidden = false; m.className = "msg" + (error ? " error" : "");
}

async function api(path, body, method) {
  const opts = { method: method || "POST", headers: {} };
  if (body instanceof FormData) opts.body = body;
  else if (body !== undefined) { opts.body = JSON.stringify(body); opts.headers["Content-Type"] = "application/json"; }
  const r = await fetch(path, opts);
  if (!r.ok) {
    let text = r.statusText;
    try { const j = await r.json(); text = j.error || (j.detail && JSON.stringify(j.detail)) || text; } catch (e) { /* not JSON */ }
    say(text, true);
    if (r.status === 409) refreshControl();
    throw new Error(text);
  }
  say("");
  return r.status === 204 || r.status === 202 ? null : r.json().catch(() => null);
}
// a command that succeeds may have made this browser the controller: redraw the badge
const act = (path, body) => api(path, body).then(refreshControl).catch(() => {});

// typed warnings ({code, message, subject}) as a list under what they doubt
function drawWarnings(el, warns) {
  el.hidden = !warns.length;
  el.innerHTML = warns.map((w) =>
    `<li data-code="${esc(w.code)}"><b>${esc(w.code)}</b>: ${esc(w.message)}${w.subject ? " (" + esc(w.subject) + ")" : ""}</li>`).join("");
}

function setVerdict(el, text, good) {
  if (!el) return;
  el.textContent = text || "";
  el.className = "verdict" + (el.classList.contains("big-verdict") ? " big-verdict" : "") + (text ? (good ? " good" : " bad") : "");
}

// ---------------------------------------------------------------- header, footer
function drawHeader() {
  const c = S.connection || {};
  const b = $("badge-conn");
  b.textContent = c.state === "operational" ? "connected" + (c.simulated ? " (simulated)" : "") : c.state === "lost" ? "link lost" : "not connected";
  b.className = "badge " + (c.state === "operational" ? "ok" : c.state === "lost" ? "bad" : "");
  const m = S.material || {}, j = S.job || {};
  let activity = "idle";
  if (["running", "pausing", "paused"].includes(m.status)) activity = "material session: " + m.message;
  else if (["bending", "paused"].includes(j.status)) activity = "bending: " + j.message;
  $("activity").textContent = activity;
}
async function refreshControl() {
  try {
    const r = await (await fetch("/api/control")).json();
    const b = $("badge-control");
    b.textContent = r.you ? "you control the machine" : r.held ? "watching (another browser controls)" : "nobody controls yet";
    b.className = "badge " + (r.you ? "ok" : r.held ? "warn" : "");
    $("take-control").hidden = r.you;
  } catch (e) { /* server away: the events badge says so */ }
}
$("take-control").onclick = () => act("/api/control", {}).then(refreshControl);
$("btn-pause").onclick = () => activeMaterial() ? act("/api/material", { command: "pause" }) : act("/api/job", { command: "pause", action: "pause" });
$("btn-resume").onclick = () => activeMaterial() ? act("/api/material", { command: "resume" }) : act("/api/job", { command: "pause", action: "resume" });
$("btn-stop").onclick = () => activeMaterial() ? act("/api/material", { command: "stop" }) : act("/api/job", { command: "cancel" });
const activeMaterial = () => ["running", "pausing", "paused"].includes((S.material || {}).status);

// ---------------------------------------------------------------- Set up
function drawSetup() {
  const c = S.connection || {}, lens = S.lens || {}, plane = S.plane || {}, kit = S.kit || {};
  setVerdict($("conn-verdict"), c.message, c.state === "operational");
  const live = $("live");
  if (c.state === "operational" && !live.src) live.src = "/api/camera/stream.mjpg?width=1280";
  $("lens-guidance").textContent = lens.guidance || "";
  $("lens-views").textContent = (lens.views || []).length + " photo(s) taken" + (lens.busy ? " — working…" : "");
  $("btn-view").disabled = $("btn-solve").disabled = !!lens.busy;
  setVerdict($("lens-verdict"), lens.verdict, lens.good);
  setVerdict($("plane-verdict"), plane.verdict, plane.good);
  setVerdict($("kit-verdict"), kit.verdict, kit.good);
  drawWarnings($("kit-warnings"), kit.warnings || []);
  $("kit-markers").innerHTML = (kit.markers || []).map((m) => `<li>${esc(m.role)}: ${esc(m.detail)}</li>`).join("");
}
function bindSetup() {
  $("btn-connect").onclick = () => act("/api/connection", { command: "connect", port: $("port").value, camera: $("camera").value });
  $("btn-view").onclick = () => act("/api/camera", { command: "view" });
  $("btn-solve").onclick = () => act("/api/camera", { command: "solve" });
  $("btn-plane").onclick = () => act("/api/camera", { command: "plane" });
  $("btn-kit").onclick = () => act("/api/camera", { command: "kit" });
}

// ---------------------------------------------------------------- Calibrate material
function drawMaterial() {
  const m = S.material || {};
  const halted = ["interrupted", "lost", "stopped"].includes(m.status);
  setVerdict($("mat-message"), m.message, !["lost", "failed", "interrupted", "stopped"].includes(m.status));
  const cont = $("btn-continue-session");
  cont.hidden = !halted; cont.textContent = `Home, then continue from bend ${m.next_bend}`;
  $("btn-discard-session").hidden = !halted;
  $("btn-start-session").disabled = ["running", "pausing", "paused"].includes(m.status) || halted;
  const total = (m.plan || []).length;
  $("mat-progress").textContent = total ? `${(m.steps || []).length} of ${total} bends done` : "";
  $("mat-steps").tBodies[0].innerHTML = (m.steps || []).map((s) =>
    `<tr><td>${s.step}</td><td>${s.direction}</td><td>${fmt(s.target_deg, 1)}</td><td>${fmt(s.loaded_deg, 3)}</td><td>${fmt(s.unloaded_deg, 3)}</td><td>${fmt(s.springback_deg, 3)}</td></tr>`).join("");
  if (m.last_photo) {
    const src = "/api/material/photo/" + encodeURIComponent(m.last_photo);
    if (!$("mat-photo").src.endsWith(src)) $("mat-photo").src = src;
    $("mat-photo-caption").textContent = `${m.last_photo}: bend ${fmt(m.last_photo_angle_deg, 3)} deg`;
    drawWarnings($("mat-photo-warnings"), m.last_photo_warnings || []);
  }
  $("mat-curve").src = "/api/material/curve.svg?n=" + (m.steps || []).length + "&s=" + encodeURIComponent(m.status);
  setVerdict($("mat-verdict"), m.verdict, m.status === "done");
  $("mat-diagnosis").textContent = m.diagnosis ? "Diagnosis: " + m.diagnosis : "";
  $("mat-calibration").hidden = !m.calibration;
  $("mat-follow-up").hidden = !m.follow_up;
}
function bindMaterial() {
  $("btn-start-session").onclick = () => {
    const text = $("angles").value.trim();
    const angles = text ? text.split(",").map(Number) : [];
    act("/api/material", { command: "start", mode: $("mode").value, angles });
  };
  $("btn-continue-session").onclick = () => act("/api/material", { command: "continue" });
  $("btn-discard-session").onclick = () => { if (confirm("Discard the unfinished session?")) act("/api/material", { command: "discard" }); };
}

// ---------------------------------------------------------------- Bend
function drawPreview(file) {
  const svg = $("preview");
  if (!file) { svg.innerHTML = ""; return; }
  const pts = file.chords_mm; const xs = pts.map((p) => p[0]), ys = pts.map((p) => p[1]);
  const x0 = Math.min(...xs), x1 = Math.max(...xs), y0 = Math.min(...ys), y1 = Math.max(...ys);
  const k = Math.min(380 / ((x1 - x0) || 1), 220 / ((y1 - y0) || 1));
  const P = pts.map((p) => [10 + (p[0] - x0) * k, 230 - (p[1] - y0) * k]);
  let body = `<polyline points="${P.map((p) => p.join(",")).join(" ")}" fill="none" stroke="#1565c0" stroke-width="3"/>`;
  P.slice(1, -1).forEach((p, i) => { body += `<circle cx="${p[0]}" cy="${p[1]}" r="3" fill="#c62828"/><text x="${p[0] + 4}" y="${p[1] - 4}" font-size="10">${fmt(file.pin_deg[i], 1)}°</text>`; });
  svg.innerHTML = body;
}
function drawBend() {
  const files = S.files || [], queue = S.queue || [], j = S.job || {};
  $("files").tBodies[0].innerHTML = files.map((f, i) =>
    `<tr><td><a href="#" data-preview="${i}">${esc(f.name)}</a></td><td>${f.bends}</td><td>${f.pin_deg.slice(0, 6).map((p) => fmt(p, 1)).join(", ")}${f.pin_deg.length > 6 ? ", …" : ""}</td><td>${fmt(f.wire_mm, 1)}</td>` +
    `<td><input type="number" min="1" value="1" size="4" data-qty="${i}"></td><td><button data-add="${i}">Add to queue</button></td></tr>`).join("");
  document.querySelectorAll("[data-add]").forEach((b) => b.onclick = () => {
    const i = b.dataset.add; act("/api/queue", { command: "add", design: files[i].name, quantity: Number(document.querySelector(`[data-qty="${i}"]`).value) });
  });
  document.querySelectorAll("[data-preview]").forEach((a) => a.onclick = (e) => { e.preventDefault(); drawPreview(files[a.dataset.preview]); });
  if (!$("preview").innerHTML && files.length) drawPreview(files[files.length - 1]);
  $("queue").tBodies[0].innerHTML = queue.map((q) =>
    `<tr><td>${esc(q.design)}</td><td>${q.done} / ${q.quantity}</td><td><button data-remove="${q.id}">Remove</button></td></tr>`).join("");
  document.querySelectorAll("[data-remove]").forEach((b) => b.onclick = () => act("/api/queue", { command: "remove", item: b.dataset.remove }));
  setVerdict($("job-message"), j.message, !["lost", "failed", "interrupted", "cancelled"].includes(j.status));
  $("job-bar").max = j.bends_total || 1; $("job-bar").value = j.bends_done || 0;
  const left = j.time_left_s === null || j.time_left_s === undefined ? "time left: learning" : `time left ${fmt(j.time_left_s, 1)} s (${j.time_left_from})`;
  $("job-progress").textContent = j.bends_total ? `bends ${j.bends_done} / ${j.bends_total} · ${left}` : "";
  $("btn-bend").disabled = ["bending", "paused", "lost"].includes(j.status);
  $("btn-bend").textContent = j.status === "interrupted" ? "Bend the cut-off part again" : "Bend the next part";
  $("btn-continue-job").hidden = j.status !== "lost";
  $("btn-continue-job").textContent = `Reconnect, then continue part ${j.part} from bend ${(j.bends_done || 0) + 1}`;
}
function upload(file) {
  const fd = new FormData(); fd.append("file", file, file.name);
  api("/api/files", fd).then((r) => say(`${r.name}: ${r.bends} bends, rules passed`)).catch(() => {});
}
function bindBend() {
  const drop = $("drop");
  drop.addEventListener("dragover", (e) => { e.preventDefault(); drop.classList.add("over"); });
  drop.addEventListener("dragleave", () => drop.classList.remove("over"));
  drop.addEventListener("drop", (e) => { e.preventDefault(); drop.classList.remove("over"); [...e.dataTransfer.files].forEach(upload); });
  $("file").onchange = (e) => [...e.target.files].forEach(upload);
  $("btn-bend").onclick = () => act("/api/job", { command: "start" });
  $("btn-continue-job").onclick = () => act("/api/job", { command: "continue" });
}

// ---------------------------------------------------------------- Inspect
function drawInspect() {
  const ins = S.inspect || {};
  const warns = ins.busy ? [] : ins.warnings || [];
  setVerdict($("ins-verdict"), ins.busy ? "measuring…" : ins.verdict, ins.passed);
  // a pass the measurement doubts is drawn amber, not green
  if (ins.passed && warns.length) $("ins-verdict").classList.replace("good", "warn");
  $("ins-message").textContent = ins.message || "";
  drawWarnings($("ins-warnings"), warns);
  $("btn-photograph").disabled = !!ins.busy;
  $("btn-correct").hidden = !(ins.verdict && !ins.corrected && !ins.busy);
  $("ins-vertices").tBodies[0].innerHTML = (ins.vertices || []).map((v) =>
    `<tr><td>${v.vertex}</td><td>${fmt(v.design_deg)}</td><td>${fmt(v.measured_deg)}</td><td class="${v.ok ? "ok" : "bad"}">${fmt(v.error_deg)}</td></tr>`).join("");
  const n = (ins.history || []).length;
  if (ins.verdict) $("ins-overlay").src = "/api/inspect/overlay.jpg?n=" + n;
  $("ins-chart").src = "/api/inspect/chart.svg?n=" + n;
}
function bindInspect() {
  $("btn-photograph").onclick = () => act("/api/inspect", { command: "photograph", tolerance_deg: Number($("tolerance").value) });
  $("btn-correct").onclick = () => act("/api/inspect", { command: "correct" });
}

// ---------------------------------------------------------------- events
const PAGES = { setup: [drawSetup, bindSetup], material: [drawMaterial, bindMaterial], bend: [drawBend, bindBend], inspect: [drawInspect, bindInspect] };
let pending = false;
function draw() {
  if (pending) return;
  pending = true;
  requestAnimationFrame(() => { pending = false; drawHeader(); PAGES[page][0](); });
}
function listen() {
  const es = new EventSource("/api/events");
  const live = $("badge-live");
  es.onopen = () => { live.textContent = "live"; live.className = "badge ok"; refreshControl(); };
  es.onerror = () => { live.textContent = "reconnecting…"; live.className = "badge bad"; };
  for (const kind of ["connection", "lens", "plane", "kit", "material", "files", "queue", "job", "inspect"]) {
    es.addEventListener(kind, (e) => { S[kind] = JSON.parse(e.data); draw(); });
  }
  es.addEventListener("control", refreshControl);
}
PAGES[page][1]();
draw();
listen();
