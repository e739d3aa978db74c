// Tessera dashboard: reads the coordinator's JSON API with the session cookie, follows
// /v1/events (server-sent events) for live updates, and sends the session's CSRF token with
// every change. No framework, no build step. Text from the farm (job names, errors) is only
// ever inserted as text, never as HTML.
"use strict";

const app = { csrf: null, view: null, live: "connecting" };

// ---------------------------------------------------------------- helpers

function h(tag, attrs, ...children) {
  const el = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs || {})) {
    if (v === null || v === undefined || v === false) continue;
    if (k.startsWith("on")) el.addEventListener(k.slice(2), v);
    else if (k === "class") el.className = v;
    // Styles through the CSSOM: the page's CSP forbids style attributes.
    else if (k === "style") Object.assign(el.style, v);
    else if (k === "dataset") Object.assign(el.dataset, v);
    else el.setAttribute(k, v === true ? "" : v);
  }
  for (const c of children.flat()) {
    if (c === null || c === undefined || c === false) continue;
    el.append(c instanceof Node ? c : document.createTextNode(String(c)));
  }
  return el;
}

async function api(path, opts = {}) {
  const method = opts.method || "GET";
  const headers = { Accept: "application/json" };
  if (method !== "GET") headers["X-CSRF-Token"] = app.csrf || "";
  let body;
  if (opts.json !== undefined) {
    headers["Content-Type"] = "application/json";
    body = JSON.stringify(opts.json);
  }
  const r = await fetch(path, { method, headers, body, credentials: "same-origin" });
  if (r.status === 401) {
    location.href = "/login";
    throw new Error("logged out");
  }
  if (r.status === 204) return null;
  const text = await r.text();
  let data = null;
  try { data = text ? JSON.parse(text) : null; } catch (_) { data = null; }
  if (!r.ok) throw new Error((data && data.error) || `${r.status} ${r.statusText}`);
  return data;
}

let toastTimer = null;
function toast(message, error = false) {
  const t = document.getElementById("toast");
  t.textContent = message;
  t.className = "toast" + (error ? " error" : "");
  t.hidden = false;
  clearTimeout(toastTimer);
  toastTimer = setTimeout(() => { t.hidden = true; }, error ? 7000 : 3000);
}

// Runs `fn` at most once per `ms`, trailing call kept.
function throttle(fn, ms) {
  let last = 0, timer = null;
  return (...args) => {
    const wait = last + ms - Date.now();
    if (wait <= 0) { last = Date.now(); fn(...args); return; }
    if (!timer) timer = setTimeout(() => { timer = null; last = Date.now(); fn(...args); }, wait);
  };
}

function duration(ms) {
  const s = Math.max(0, Math.round(ms / 1000));
  if (s < 60) return `${s}s`;
  if (s < 3600) return `${Math.floor(s / 60)}m ${String(s % 60).padStart(2, "0")}s`;
  return `${Math.floor(s / 3600)}h ${String(Math.floor((s % 3600) / 60)).padStart(2, "0")}m`;
}
const ago = (t) => (t ? duration(Date.now() - t) + " ago" : "—");
const when = (t) => (t ? new Date(t).toLocaleString() : "—");

function timing(j) {
  if (!j.started_ms) return ["—", "—"];
  const elapsed = (j.finished_ms || Date.now()) - j.started_ms;
  const final = ["done", "failed", "cancelled", "paused"].includes(j.state);
  const eta = final || j.progress <= 0 ? "—" : duration((elapsed * (1 - j.progress)) / j.progress);
  return [duration(elapsed), eta];
}

const badge = (state, text) => h("span", { class: `badge ${state}` }, text || state);

function progress(p, state) {
  const pct = Math.round(p * 1000) / 10;
  return h("div", { class: "progress" },
    h("div", { class: `bar ${state}` }, h("span", { style: { width: `${Math.min(100, pct)}%` } })),
    h("span", { class: "pct" }, `${pct}%`));
}

async function act(promise, ok) {
  try {
    await promise;
    if (ok) toast(ok);
    app.view && app.view.refresh();
  } catch (e) {
    toast(e.message, true);
  }
}

// The actions a job's state allows, as buttons.
function jobActions(j, small) {
  const cls = small ? "small" : "";
  const b = (label, fn, extra = "") =>
    h("button", { class: `${cls} ${extra}`, type: "button", onclick: fn, dataset: { action: label.toLowerCase() } }, label);
  const post = (what) => () => act(api(`/v1/jobs/${j.id}/${what}`, { method: "POST" }), `Job ${j.id}: ${what}`);
  const out = [];
  if (j.state === "queued" || j.state === "running") out.push(b("Pause", post("pause")));
  if (j.state === "paused") out.push(b("Resume", post("resume")));
  if (["queued", "running", "paused"].includes(j.state))
    out.push(b("Cancel", () => { if (confirm(`Cancel job ${j.id} "${j.name}"?`)) post("cancel")(); }, "danger"));
  if (j.state === "failed" || j.state === "cancelled") out.push(b("Requeue", post("requeue")));
  if (["done", "failed", "cancelled"].includes(j.state))
    out.push(b("Delete", () => {
      if (!confirm(`Delete job ${j.id} "${j.name}" with its frames?`)) return;
      // The job's page asks nothing more of a job being deleted (a question after the delete
      // would be a 404).
      const view = app.view && app.view.jobId === j.id ? app.view : null;
      if (view) view.gone = true;
      act(api(`/v1/jobs/${j.id}`, { method: "DELETE" }).then(() => {
        if (view) navigate("/");
      }, (e) => {
        if (view) view.gone = false;
        throw e;
      }), `Job ${j.id} deleted`);
    }, "danger"));
  return out;
}

function setPriority(j, p) {
  return act(api(`/v1/jobs/${j.id}`, { method: "PATCH", json: { priority: p } }), `Job ${j.id}: priority ${p}`);
}

// ---------------------------------------------------------------- jobs list

const STATES = ["running", "queued", "paused", "done", "failed", "cancelled"];
const ENDED = ["done", "failed", "cancelled"];

class JobsView {
  constructor(params) {
    this.state = params.get("state") || "";
    this.q = params.get("q") || "";
    this.sort = params.get("sort") || "newest";
    this.offset = Number(params.get("offset") || 0);
    this.limit = 50;
    this.refresh = throttle(() => this.load(), 700);
  }
  mount(root) {
    this.root = root;
    this.search = h("input", { type: "search", placeholder: "Filter by name", value: this.q, "aria-label": "Filter by name" });
    this.search.addEventListener("input", throttle(() => { this.q = this.search.value; this.offset = 0; this.sync(); this.load(); }, 300));
    this.sortSel = h("select", { "aria-label": "Order", onchange: () => { this.sort = this.sortSel.value; this.offset = 0; this.sync(); this.load(); } },
      h("option", { value: "newest" }, "Newest first"),
      h("option", { value: "queue" }, "Queue order"));
    this.sortSel.value = this.sort;
    this.chips = h("div", { class: "filters" });
    this.body = h("div");
    this.pager = h("div", { class: "pager" });
    root.append(
      h("div", { class: "page-head" }, h("h1", {}, "Jobs"),
        h("div", { class: "actions" }, this.sortSel)),
      this.chips, this.body, this.pager);
    this.load();
  }
  sync() {
    const p = new URLSearchParams();
    if (this.state) p.set("state", this.state);
    if (this.q) p.set("q", this.q);
    if (this.sort !== "newest") p.set("sort", this.sort);
    if (this.offset) p.set("offset", this.offset);
    const qs = p.toString();
    history.replaceState(null, "", "/" + (qs ? "?" + qs : ""));
  }
  onEvent(e) { if (e.type === "job" || e.type === "job_deleted") this.refresh(); }
  async load() {
    const p = new URLSearchParams({ limit: this.limit, offset: this.offset });
    if (this.state) p.set("state", this.state);
    if (this.q) p.set("q", this.q);
    if (this.sort === "queue") p.set("sort", "queue");
    let list;
    try { list = await api("/v1/jobs?" + p); } catch (e) { toast(e.message, true); return; }
    if (!this.root.isConnected) return;
    this.renderChips(list.by_state);
    this.renderTable(list);
  }
  renderChips(byState) {
    const all = Object.values(byState).reduce((a, b) => a + b, 0);
    const chip = (value, label, n) => h("button", {
      type: "button", class: "chip" + (this.state === value ? " on" : ""), dataset: { state: value || "all" },
      onclick: () => { this.state = value; this.offset = 0; this.sync(); this.load(); },
    }, label, h("span", { class: "count" }, n));
    this.chips.replaceChildren(chip("", "All", all),
      ...STATES.map((s) => chip(s, s[0].toUpperCase() + s.slice(1), byState[s] || 0)), this.search);
  }
  renderTable(list) {
    if (!list.jobs.length) {
      this.body.replaceChildren(h("div", { class: "table-wrap" }, h("div", { class: "empty" },
        list.total === 0 && !this.state && !this.q ? "No jobs yet. Submit one with `tessera submit scene.json`." : "No jobs match.")));
      this.pager.replaceChildren();
      return;
    }
    const rows = list.jobs.map((j) => {
      const [elapsed, eta] = timing(j);
      const up = h("button", { class: "small", type: "button", title: "Raise priority", "aria-label": `Raise priority of job ${j.id}`, onclick: () => setPriority(j, j.priority + 1) }, "▲");
      const down = h("button", { class: "small", type: "button", title: "Lower priority", "aria-label": `Lower priority of job ${j.id}`, onclick: () => setPriority(j, j.priority - 1) }, "▼");
      return h("tr", { dataset: { job: j.id } },
        h("td", { class: "num mono" }, j.id),
        h("td", {}, h("a", { href: `/jobs/${j.id}`, "data-link": true }, j.name)),
        h("td", { class: "submitter" }, j.submitter || "—"),
        h("td", {}, badge(j.state)),
        h("td", {}, progress(j.progress, j.state)),
        h("td", {}, h("div", { class: "priority" }, h("span", { class: "mono", dataset: { priority: j.priority } }, j.priority), up, down)),
        h("td", {}, j.measuring ? "auto (measuring)" : j.method),
        h("td", { class: "mono" }, j.frames.first === j.frames.last ? j.frames.first : `${j.frames.first}–${j.frames.last}`),
        h("td", { class: "mono" }, `${j.width}×${j.height}`),
        h("td", { class: "num" }, elapsed),
        h("td", { class: "num" }, eta),
        h("td", { class: "actions" }, jobActions(j, true)));
    });
    this.body.replaceChildren(h("div", { class: "table-wrap" }, h("table", { id: "jobs" },
      h("thead", {}, h("tr", {}, ["ID", "Name", "Submitter", "State", "Progress", "Priority", "Method", "Frames", "Size", "Elapsed", "ETA", ""].map((t) => h("th", {}, t)))),
      h("tbody", {}, rows))));
    const from = this.offset + 1, to = this.offset + list.jobs.length;
    this.pager.replaceChildren(
      h("span", {}, `${from}–${to} of ${list.total}`),
      h("button", { type: "button", disabled: this.offset === 0, onclick: () => { this.offset = Math.max(0, this.offset - this.limit); this.sync(); this.load(); } }, "‹ Newer"),
      h("button", { type: "button", disabled: to >= list.total, onclick: () => { this.offset += this.limit; this.sync(); this.load(); } }, "Older ›"));
  }
}

// ---------------------------------------------------------------- one job

const TASK_COLOURS = { queued: "#9aa3b2", waiting: "#c5cad3", leased: "#f0a31a", done: "#23a26d", failed: "#d9434d", cancelled: "#4a5162" };

class JobView {
  constructor(id) {
    this.jobId = id;
    this.frame = null;
    this.previewN = 0;
    this.refresh = throttle(() => this.load(), 800);
    this.refreshPreview = throttle(() => this.loadPreview(), 1500);
  }
  mount(root) {
    this.root = root;
    this.head = h("div", { class: "page-head" });
    this.banner = h("div");
    this.stats = h("div", { class: "stats" });
    this.framesBox = h("div", { class: "frames", id: "frames" });
    this.canvas = h("canvas", { id: "tilemap", width: 16, height: 9 });
    this.img = h("img", { id: "preview", alt: "Live preview of the frame" });
    this.imgBox = h("div", { class: "canvas-box" }, this.img, h("div", { class: "ph" }, "No preview yet"));
    this.details = h("div", { class: "row" });
    this.attempts = h("div");
    this.frameTitle = h("h2", {}, "Frame");
    root.append(this.head, this.banner, this.stats,
      h("div", { class: "panel mt" }, h("h2", {}, "Frames"), this.framesBox),
      h("div", { class: "panel" }, this.frameTitle,
        h("div", { class: "viewer" },
          h("div", {}, h("div", { class: "canvas-box" }, this.canvas),
            h("div", { class: "legend" }, ...["queued", "leased", "done", "failed"].map((s) => h("span", {}, h("i", { style: { background: TASK_COLOURS[s] } }), s === "leased" ? "rendering" : s)))),
          h("div", {}, this.imgBox, h("div", { class: "legend" }, "Live preview: what the results folded so far make")))),
      h("div", { class: "mt" }, this.details),
      this.attempts);
    this.img.addEventListener("load", () => { const ph = this.imgBox.querySelector(".ph"); if (ph) ph.hidden = true; });
    this.load();
  }
  onEvent(e) {
    if (e.type === "job_deleted" && e.id === this.jobId) { this.gone = true; return; }
    if (e.type === "job" && e.id === this.jobId) { this.refresh(); this.refreshPreview(); }
    // Workers' leases change the tile map of a job that runs; an ended job has none.
    if (e.type === "worker" && !(this.job && ENDED.includes(this.job.state))) this.refresh();
  }
  async load() {
    if (this.gone || !this.root.isConnected) return;
    let j;
    try { j = await api(`/v1/jobs/${this.jobId}`); } catch (e) {
      if (!this.root.isConnected) return;
      this.root.replaceChildren(h("div", { class: "panel empty" }, e.message, " ", h("a", { href: "/", "data-link": true }, "Back to jobs")));
      return;
    }
    if (!this.root.isConnected) return;
    this.job = j;
    document.title = `${j.name} · Tessera`;
    this.renderHead(j);
    this.renderStats(j);
    this.renderFrames(j);
    this.renderDetails(j);
    await Promise.all([this.loadTiles(), this.loadAttempts()]);
    if (this.previewN === 0) this.loadPreview();
  }
  renderHead(j) {
    const input = h("input", { type: "number", value: j.priority, "aria-label": "Priority", id: "priority" });
    this.head.replaceChildren(
      h("h1", {}, j.name), badge(j.state), h("span", { class: "muted mono" }, `job ${j.id}`),
      h("div", { class: "actions" },
        h("form", { class: "priority", onsubmit: (e) => { e.preventDefault(); setPriority(j, Number(input.value)); } },
          h("label", { for: "priority", class: "muted" }, "Priority"), input, h("button", { type: "submit" }, "Set")),
        jobActions(j, false)));
    this.banner.replaceChildren(...(j.error ? [h("div", { class: "error-banner", role: "alert" }, j.error)] : []));
  }
  renderStats(j) {
    const [elapsed, eta] = timing(j);
    const t = j.tasks;
    const stat = (label, value, sub) => h("div", { class: "stat" }, h("div", { class: "label" }, label), h("div", { class: "value" }, value), sub ? h("div", { class: "sub" }, sub) : null);
    this.stats.replaceChildren(
      stat("Progress", `${(j.progress * 100).toFixed(1)}%`, progress(j.progress, j.state)),
      stat("Tasks", `${t.done} / ${Math.max(t.total, t.planned)}`, `${t.leased} rendering · ${t.queued} queued · ${t.failed} failed`),
      stat("Elapsed", elapsed, `ETA ${eta}`),
      stat("Method", j.measuring ? "auto: measuring on a worker" : j.method, `${j.width}×${j.height} · ${j.spp} spp`),
      stat("Attempts", j.attempts, `since ${when(j.created_ms)}`));
  }
  renderFrames(j) {
    const frames = j.frame_status;
    if (this.frame === null || !frames.some((f) => f.frame === this.frame)) {
      const running = frames.find((f) => f.state === "running");
      const done = frames.filter((f) => f.state === "done");
      this.frame = (running || done[done.length - 1] || frames[0] || { frame: 1 }).frame;
    }
    this.framesBox.replaceChildren(...frames.map((f) => h("button", {
      type: "button", class: `frame ${f.state}${f.frame === this.frame ? " sel" : ""}`,
      title: `Frame ${f.frame}: ${f.state}, ${f.tasks_done}/${f.tasks_total} tasks`,
      onclick: () => { this.frame = f.frame; this.previewN = 0; this.load(); },
    }, f.frame)));
    const f = frames.find((x) => x.frame === this.frame);
    this.frameTitle.replaceChildren(...[`Frame ${this.frame}`, " ", f ? badge(f.state) : null,
      f && f.estimated_rel_mse ? h("span", { class: "muted" }, ` estimated relMSE ${f.estimated_rel_mse.toExponential(2)}`) : null,
      f && f.exr ? h("span", {}, " · ", h("a", { href: f.exr, download: `frame_${String(f.frame).padStart(4, "0")}.exr` }, "Download EXR")) : null].filter((x) => x !== null));
  }
  async loadTiles() {
    const j = this.job;
    let tasks;
    try { tasks = await api(`/v1/jobs/${j.id}/tasks?frame=${this.frame}`); } catch (_) { return; }
    const c = this.canvas;
    const scale = Math.min(1, 960 / j.width);
    c.width = Math.max(1, Math.round(j.width * scale));
    c.height = Math.max(1, Math.round(j.height * scale));
    const g = c.getContext("2d");
    g.fillStyle = "#1a1f2a";
    g.fillRect(0, 0, c.width, c.height);
    const order = { done: 0, cancelled: 0, queued: 1, waiting: 1, leased: 2, failed: 3 };
    // Later steps (adaptive rounds) paint over earlier ones; within a step the busiest state shows.
    tasks.sort((a, b) => a.step - b.step || order[a.state] - order[b.state]);
    for (const t of tasks) {
      if (t.x1 <= t.x0 || t.y1 <= t.y0) continue;
      g.fillStyle = TASK_COLOURS[t.state] || "#9aa3b2";
      g.fillRect(t.x0 * scale, t.y0 * scale, (t.x1 - t.x0) * scale, (t.y1 - t.y0) * scale);
      g.strokeStyle = "rgba(16,20,28,.55)";
      g.lineWidth = 1;
      g.strokeRect(t.x0 * scale + 0.5, t.y0 * scale + 0.5, (t.x1 - t.x0) * scale - 1, (t.y1 - t.y0) * scale - 1);
    }
    c.dataset.tasks = tasks.length;
    c.dataset.done = tasks.filter((t) => t.state === "done").length;
  }
  loadPreview() {
    const j = this.job;
    if (!j || this.gone || !this.root.isConnected) return;
    const f = j.frame_status.find((x) => x.frame === this.frame);
    if (!f || f.state === "queued") return;
    const next = new Image();
    const url = `/v1/jobs/${j.id}/frames/${this.frame}/preview.png?n=${++this.previewN}`;
    next.onload = () => { this.img.src = url; this.img.dataset.n = this.previewN; };
    next.src = url;
  }
  async loadAttempts() {
    let list;
    try { list = await api(`/v1/jobs/${this.jobId}/attempts?failures_first=true&limit=100`); } catch (_) { return; }
    const failures = list.filter((a) => ["failed", "expired", "unreadable"].includes(a.outcome));
    const shown = this.allAttempts ? list : list.slice(0, Math.max(15, failures.length));
    const more = list.length > shown.length
      ? h("button", { type: "button", class: "small mt", onclick: () => { this.allAttempts = true; this.loadAttempts(); } }, `Show all ${list.length}`)
      : null;
    const rows = shown.map((a) => h("tr", {},
      h("td", { class: "mono num" }, a.task_id),
      h("td", {}, `${a.kind} ${a.index}`, h("span", { class: "muted" }, a.frame ? ` · frame ${a.frame}` : " · pass")),
      h("td", { class: "mono" }, a.worker),
      h("td", {}, a.outcome ? badge(a.outcome === "done" ? "done" : ["failed", "expired", "unreadable"].includes(a.outcome) ? "failed" : "cancelled", a.outcome) : badge("running", "running")),
      h("td", { class: "num" }, a.ended_ms ? duration(a.ended_ms - a.started_ms) : ago(a.started_ms)),
      h("td", {}, a.error || "")));
    this.attempts.replaceChildren(h("div", { class: "panel mt" },
      h("h2", {}, "Attempts ", h("span", { class: "muted" }, failures.length ? `${failures.length} failed (shown first)` : "no failures")),
      list.length ? h("div", { class: "table-wrap" }, h("table", { id: "attempts" },
        h("thead", {}, h("tr", {}, ["Task", "What", "Worker", "Outcome", "Time", "Error"].map((t) => h("th", {}, t)))),
        h("tbody", {}, rows))) : h("div", { class: "empty" }, "No task leased yet."), more));
  }
  renderDetails(j) {
    const passes = j.passes.length ? h("ul", { class: "plain" }, j.passes.map((p) => h("li", {},
      h("strong", {}, p.name), " ", badge(p.state === "built" || p.state === "reused" ? "done" : p.state === "running" ? "running" : "queued", p.state),
      h("span", { class: "muted" }, ` ${p.tasks_done}/${p.tasks_total} tasks`),
      p.bytes ? h("span", { class: "muted" }, ` · ${(p.bytes / 1048576).toFixed(1)} MiB`) : null,
      p.built_by && p.built_by !== j.id ? h("span", {}, " · built by ", h("a", { href: `/jobs/${p.built_by}`, "data-link": true }, `job ${p.built_by}`)) : null,
      p.summary ? h("div", { class: "muted" }, p.summary) : null))) : h("p", { class: "muted" }, "None: this job needs no precomputation.");
    const blocked = j.blocklist.length ? h("ul", { class: "plain", id: "blocklist" }, j.blocklist.map((b) => h("li", {},
      badge("blocked", "blocklisted"), " ", h("span", { class: "mono" }, b.worker), h("span", { class: "muted" }, ` after ${b.failures} failures, ${ago(b.since_ms)}`),
      " ", h("button", { class: "small", type: "button", onclick: () => act(api(`/v1/workers/${encodeURIComponent(b.worker)}/unblock?job=${j.id}`, { method: "POST" }), `${b.worker} may run job ${j.id} again`) }, "Unblock"),
      b.last_error ? h("div", { class: "muted" }, b.last_error) : null))) : h("p", { class: "muted" }, "No worker is blocklisted for this job.");
    const settings = h("dl", { class: "kv" },
      h("dt", {}, "Scene"), h("dd", { class: "mono" }, j.scene),
      h("dt", {}, "Bundle"), h("dd", { class: "mono" }, j.bundle.slice(0, 16) + "…"),
      h("dt", {}, "Frames"), h("dd", {}, `${j.frames.first}–${j.frames.last}`),
      h("dt", {}, "Requires"), h("dd", {}, j.require_tags.length ? j.require_tags.map((t) => h("span", { class: "tag" }, t)) : "any worker"),
      h("dt", {}, "Submitted"), h("dd", {}, when(j.created_ms), j.submitter ? ` by ${j.submitter}` : ""),
      h("dt", {}, "Finished"), h("dd", {}, when(j.finished_ms)));
    this.details.replaceChildren(
      h("div", { class: "panel" }, h("h2", {}, "Decisions"), h("ul", { class: "plain", id: "decisions" }, j.decisions.map((d) => h("li", {}, d)))),
      h("div", { class: "stack" },
        h("div", { class: "panel" }, h("h2", {}, "Job"), settings),
        h("div", { class: "panel" }, h("h2", {}, "Passes"), passes),
        h("div", { class: "panel" }, h("h2", {}, "Blocklist"), blocked)));
  }
}

// ---------------------------------------------------------------- workers

class WorkersView {
  constructor() { this.refresh = throttle(() => this.load(), 800); }
  mount(root) {
    this.root = root;
    this.body = h("div");
    root.append(h("div", { class: "page-head" }, h("h1", {}, "Workers")), this.body);
    this.load();
    this.tick = setInterval(() => this.load(), 5000);
  }
  unmount() { clearInterval(this.tick); }
  onEvent(e) { if (e.type === "worker") this.refresh(); }
  async load() {
    let list;
    try { list = await api("/v1/workers"); } catch (e) { toast(e.message, true); return; }
    if (!this.root.isConnected) return;
    if (!list.length) {
      this.body.replaceChildren(h("div", { class: "table-wrap" }, h("div", { class: "empty" }, "No worker has connected. Start one with `tessera worker --coordinator URL --token WORKER_TOKEN`, or `tessera serve --local-workers N`.")));
      return;
    }
    list.sort((a, b) => (b.alive - a.alive) || (b.last_seen_ms - a.last_seen_ms));
    const rows = list.map((w) => {
      const state = !w.alive ? "gone" : w.draining ? "draining" : w.leased_tasks.length ? "busy" : "idle";
      const toggle = w.draining
        ? h("button", { class: "small", type: "button", dataset: { action: "undrain" }, onclick: () => act(api(`/v1/workers/${encodeURIComponent(w.id)}/undrain`, { method: "POST" }), `${w.name} takes work again`) }, "Undrain")
        : h("button", { class: "small", type: "button", dataset: { action: "drain" }, onclick: () => act(api(`/v1/workers/${encodeURIComponent(w.id)}/drain`, { method: "POST" }), `${w.name} drains`) }, "Drain");
      return h("tr", { dataset: { worker: w.id } },
        h("td", {}, h("div", {}, w.name), h("div", { class: "muted mono" }, w.id)),
        h("td", {}, badge(state)),
        h("td", { class: "mono" }, w.leased_tasks.length ? w.leased_tasks.join(", ") : "—"),
        h("td", {}, w.tags.length ? w.tags.map((t) => h("span", { class: "tag" }, t)) : h("span", { class: "muted" }, "—")),
        h("td", { class: "num" }, w.samples_per_second ? `${(w.samples_per_second / 1e6).toFixed(2)} M` : "—"),
        h("td", { class: "num" }, w.cpu !== null && w.cpu !== undefined ? `${w.cpu.toFixed(1)} / ${w.slots}` : "—"),
        h("td", { class: "num" }, ago(w.last_seen_ms)),
        h("td", { class: "num" }, w.tasks_done),
        h("td", { class: "num" }, w.failures),
        h("td", {}, w.blocklisted_for.length
          ? w.blocklisted_for.map((id) => h("span", { class: "blocked-for" }, badge("blocked", "blocklisted"), " ", h("a", { href: `/jobs/${id}`, "data-link": true }, `job ${id}`), " ",
              h("button", { class: "small", type: "button", dataset: { action: "unblock" }, onclick: () => act(api(`/v1/workers/${encodeURIComponent(w.id)}/unblock?job=${id}`, { method: "POST" }), `${w.name} may run job ${id} again`) }, "Unblock")))
          : h("span", { class: "muted" }, "—")),
        h("td", { class: "actions" }, toggle));
    });
    this.body.replaceChildren(h("div", { class: "table-wrap" }, h("table", { id: "workers" },
      h("thead", {}, h("tr", {}, ["Worker", "State", "Tasks", "Tags", "Samples/s", "CPU (cores)", "Heartbeat", "Done", "Failures", "Blocklisted", ""].map((t) => h("th", {}, t)))),
      h("tbody", {}, rows))));
  }
}

// ---------------------------------------------------------------- routing and live updates

function route() {
  const path = location.pathname;
  const params = new URLSearchParams(location.search);
  let m;
  if ((m = path.match(/^\/jobs\/(\d+)$/))) return [new JobView(Number(m[1])), "jobs"];
  if (path === "/workers") return [new WorkersView(), "workers"];
  return [new JobsView(params), "jobs"];
}

function render() {
  if (app.view && app.view.unmount) app.view.unmount();
  const [view, nav] = route();
  app.view = view;
  document.title = "Tessera";
  for (const a of document.querySelectorAll("[data-nav]")) a.classList.toggle("active", a.dataset.nav === nav);
  const root = document.getElementById("view");
  root.replaceChildren();
  view.mount(root);
}

function navigate(path) {
  history.pushState(null, "", path);
  render();
}

function setLive(mode) {
  const el = document.getElementById("live");
  el.className = "live " + mode;
  el.textContent = mode === "on" ? "live" : mode === "poll" ? "polling" : "connecting…";
  app.live = mode;
}

let pollTimer = null;
function listen() {
  const es = new EventSource("/v1/events");
  es.addEventListener("open", () => { setLive("on"); clearInterval(pollTimer); pollTimer = null; });
  es.addEventListener("change", (m) => {
    let e;
    try { e = JSON.parse(m.data); } catch (_) { return; }
    if (app.view && app.view.onEvent) app.view.onEvent(e);
  });
  es.addEventListener("resync", () => app.view && app.view.refresh());
  es.addEventListener("error", () => {
    // The browser reconnects by itself; poll meanwhile.
    setLive("poll");
    if (!pollTimer) pollTimer = setInterval(() => app.view && app.view.refresh(), 5000);
  });
}

document.addEventListener("click", (e) => {
  const a = e.target.closest("a[data-link]");
  if (!a || e.ctrlKey || e.metaKey || e.shiftKey || e.button !== 0) return;
  e.preventDefault();
  navigate(a.getAttribute("href"));
});
window.addEventListener("popstate", render);

document.addEventListener("DOMContentLoaded", async () => {
  try {
    const s = await api("/v1/session");
    app.csrf = s.csrf;
    document.getElementById("logout-csrf").value = s.csrf;
    document.getElementById("whoami").textContent = `${s.user} (${s.role})`;
  } catch (e) {
    location.href = "/login";
    return;
  }
  render();
  listen();
});
