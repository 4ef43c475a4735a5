// The trajcache admin dashboard: reads /v1/stats, /v1/stats/top-trajectories, /v1/plan-events,
// /v1/seed-jobs and /v1/trajectories/{id}, and redraws everything on a timer. The 3D view
// (view3d.js) shows the inspected trajectory, or a plan event picked in the events table.
//
// One selection drives the 3D view, the trajectory inspector and the usage history: picking a
// trajectory shows it in all three; picking a plan event (its 3D link, or `#event=N` in the
// address) opens it in the 3D view, which reports the trajectory it shows (the event's, or the
// rejected candidate at fault), and the inspector and the usage history follow that one.
"use strict";

(() => {
  const KEY_STORAGE = "trajcache.adminKey";
  const $ = (id) => document.getElementById(id);
  const state = { timer: null, busy: false, again: false, stats: null, refreshes: 0, models: new Map(), inspected: null, viewed: null, awaitingView: false };

  // --- formatting ---------------------------------------------------------------------------

  const pad = (n) => String(n).padStart(2, "0");
  const fmtInt = (n) => (n === null || n === undefined ? "–" : Math.round(n).toLocaleString("en-US"));
  const fmtPct = (r) => (r === null || r === undefined ? "–" : `${(r * 100).toFixed(1)} %`);
  function fmtMs(ms) {
    if (ms === null || ms === undefined) return "–";
    if (ms >= 60000) return `${(ms / 60000).toFixed(1)} min`;
    if (ms >= 1000) return `${(ms / 1000).toFixed(2)} s`;
    if (ms >= 10) return `${ms.toFixed(0)} ms`;
    return `${ms.toFixed(ms >= 1 ? 1 : 2)} ms`;
  }
  function fmtTime(iso) {
    const d = new Date(iso);
    return `${pad(d.getUTCHours())}:${pad(d.getUTCMinutes())}:${pad(d.getUTCSeconds())}`;
  }
  function fmtDateTime(iso) {
    if (!iso) return "–";
    const d = new Date(iso);
    return `${d.getUTCFullYear()}-${pad(d.getUTCMonth() + 1)}-${pad(d.getUTCDate())} ${fmtTime(iso)}`;
  }
  function fmtSpan(seconds) {
    if (seconds < 60) return `${seconds} s`;
    if (seconds < 3600) return `${seconds / 60} min`;
    if (seconds < 86400) return `${seconds / 3600} h`;
    return `${seconds / 86400} d`;
  }
  const shortId = (id) => (id && id.length > 12 ? `${id.slice(0, 10)}…` : id || "–");
  // The robot id of a seed job's plan events; its stats group has requester "seed_job".
  const seedJobKey = (jobId) => `seed-job-${jobId}`;
  const SEED_JOBS_LISTED = 20;
  const REFUSALS_LISTED = 10;

  function timeAxis(bucketS) {
    const format = (t) => {
      const d = new Date(t);
      if (bucketS >= 86400) return `${pad(d.getUTCMonth() + 1)}-${pad(d.getUTCDate())}`;
      if (bucketS < 60) return fmtTime(d.toISOString());
      return `${pad(d.getUTCHours())}:${pad(d.getUTCMinutes())}`;
    };
    const xTicks = (lo, hi) => {
      const step = bucketS * 1000;
      const count = Math.max(1, Math.round((hi - lo) / step));
      const every = Math.max(1, Math.ceil(count / 6));
      const out = [];
      for (let i = 0; i <= count; i += every) out.push(lo + i * step);
      return out;
    };
    return { xFormat: format, xTicks };
  }

  // --- the API ------------------------------------------------------------------------------

  class AuthNeeded extends Error {}

  async function api(path) {
    const headers = { Accept: "application/json" };
    const key = sessionStorage.getItem(KEY_STORAGE);
    if (key) headers.Authorization = `Bearer ${key}`;
    const reply = await fetch(path, { headers, cache: "no-store" });
    if (reply.status === 401 || reply.status === 403) {
      const body = await reply.json().catch(() => ({}));
      throw new AuthNeeded(body.detail || "an admin key is required");
    }
    if (!reply.ok) {
      const body = await reply.json().catch(() => ({}));
      throw new Error(`${path}: ${reply.status} ${body.detail || reply.statusText}`);
    }
    return reply.json();
  }

  // A model's name (given at registration, else its robot's) and state names, asked once.
  async function modelInfo(modelId) {
    if (!state.models.has(modelId)) {
      const model = await api(`/v1/robot-models/${encodeURIComponent(modelId)}`);
      state.models.set(modelId, { name: model.name, stateNames: model.state_names });
    }
    return state.models.get(modelId);
  }

  // Ask for the models not known yet (a refusal of an unknown robot names none).
  async function knowModels(ids) {
    const wanted = [...new Set(ids)].filter((id) => id && !state.models.has(id));
    await Promise.all(wanted.map((id) => modelInfo(id).catch((err) => {
      if (err instanceof AuthNeeded) throw err;
    })));
  }

  // A model by name, its hash on hover.
  function modelCell(td, modelId) {
    const known = modelId && state.models.get(modelId);
    td.textContent = known ? known.name : shortId(modelId);
    td.title = modelId || "";
    td.className = "model";
    return td;
  }

  // --- rendering ----------------------------------------------------------------------------

  function cell(tr, text, cls) {
    const td = document.createElement("td");
    td.textContent = text;
    if (cls) td.className = cls;
    tr.appendChild(td);
    return td;
  }

  function trajectoryLink(td, id) {
    td.textContent = "";
    if (id === null || id === undefined) { td.textContent = "–"; return; }
    const a = document.createElement("a");
    a.className = "traj";
    a.textContent = `#${id}`;
    a.addEventListener("click", () => pickTrajectory(id).catch((err) => setStatus(String(err.message || err), true)));
    td.appendChild(a);
  }

  function fillTable(table, rows, columns, emptyText) {
    const body = table.querySelector("tbody");
    body.textContent = "";
    if (!rows.length) {
      const tr = document.createElement("tr");
      const td = cell(tr, emptyText, "empty");
      td.colSpan = columns;
      body.appendChild(tr);
      return;
    }
    for (const row of rows) body.appendChild(row);
  }

  function renderKpis(stats) {
    const t = stats.totals;
    const uncredited = t.uncredited_hits ? `${fmtInt(t.uncredited_hits)} hits without an estimate` : "median planning time per hit";
    const items = [
      ["Requests", fmtInt(t.requests), `in the last ${stats.window}`],
      ["Hit rate", fmtPct(t.hit_rate), `${fmtInt(t.hits)} served from the cache`],
      ["Planner calls", fmtInt(t.planner_calls), `${fmtInt(t.repaired || 0)} repaired cached paths · planning p50 ${fmtMs(t.plan_ms.p50)}`],
      ["Failures", fmtInt(t.failures), `${fmtInt(t.misses)} misses`],
      ["Refusals", fmtInt(t.refusals), "refused plans (4xx): not answered, not failures"],
      ["Time saved", fmtMs(t.time_saved_ms), uncredited],
      ["Lookup + validation p50", fmtMs(sum(t.lookup_ms.p50, t.validate_ms.p50)), `validation p95 ${fmtMs(t.validate_ms.p95)}`],
    ];
    const box = $("kpis");
    box.textContent = "";
    for (const [label, value, note] of items) {
      const div = document.createElement("div");
      div.className = "kpi";
      div.innerHTML = '<div class="label"></div><div class="value"></div><div class="note"></div>';
      div.querySelector(".label").textContent = label;
      div.querySelector(".value").textContent = value;
      div.querySelector(".note").textContent = note;
      box.appendChild(div);
    }
  }

  function sum(a, b) {
    return a === null || b === null ? null : a + b;
  }

  // Time charts share one x axis: buckets from their start to the next one's; points at the middle.
  function timeFrame(stats) {
    const step = stats.bucket_s * 1000;
    const starts = stats.series.map((b) => Date.parse(b.start));
    return {
      starts,
      mids: starts.map((x) => x + step / 2),
      opts: { ...timeAxis(stats.bucket_s), xMin: starts[0], xMax: starts[starts.length - 1] + step },
    };
  }

  function renderCharts(stats) {
    const { starts, mids, opts } = timeFrame(stats);
    const P = Charts.PALETTE;
    const seconds = (v) => `${+v.toFixed(2)} s`;
    Charts.line(
      $("chart-hit-rate"),
      [{ name: "hit rate", color: P[0], points: stats.series.map((b, i) => [mids[i], b.hit_rate === null ? null : b.hit_rate * 100]) }],
      { ...opts, yMin: 0, yMax: 100, yFormat: (v) => `${v.toFixed(0)} %`, emptyText: "No requests in this window" },
    );
    let cumulative = 0;
    if (!stats.series.some((b) => b.time_saved_ms > 0)) {
      Charts.empty($("chart-time-saved"), "No time saved in this window");
    } else Charts.line(
      $("chart-time-saved"),
      [
        { name: "per bucket", color: P[2], points: stats.series.map((b, i) => [mids[i], b.time_saved_ms / 1000]) },
        { name: "cumulative", color: P[4], points: stats.series.map((b, i) => [mids[i], (cumulative += b.time_saved_ms) / 1000]) },
      ],
      { ...opts, yMin: 0, yFormat: seconds, dots: false, legend: true, emptyText: "No time saved in this window" },
    );
    Charts.bars(
      $("chart-calls"),
      starts,
      [
        { name: "hits", color: P[0], values: stats.series.map((b) => b.hits) },
        { name: "planner calls", color: P[3], values: stats.series.map((b) => b.planner_calls - b.failures) },
        { name: "failures", color: P[1], values: stats.series.map((b) => b.failures) },
        { name: "misses", color: P[8], values: stats.series.map((b) => b.misses) },
        { name: "refusals", color: P[5], values: stats.series.map((b) => b.refusals) },
      ],
      { ...opts, yFormat: (v) => fmtInt(v), emptyText: "No requests in this window" },
    );
    renderLatency(stats);
  }

  function renderLatency(stats) {
    const metric = $("latency-metric").value;
    const { mids, opts } = timeFrame(stats);
    const P = Charts.PALETTE;
    Charts.line(
      $("chart-latency"),
      ["p50", "p95", "p99"].map((q, k) => ({
        name: q,
        color: [P[2], P[3], P[1]][k],
        points: stats.series.map((b, i) => [mids[i], b[metric][q]]),
      })),
      { ...opts, log: true, yFormat: fmtMs, emptyText: "No timings in this window" },
    );
  }

  function renderRobots(stats) {
    const robots = stats.groups.filter((g) => g.requester === "robot");
    const rows = robots.map((g) => {
      const tr = document.createElement("tr");
      cell(tr, g.key);
      cell(tr, fmtInt(g.requests), "num");
      cell(tr, fmtPct(g.hit_rate), "num");
      cell(tr, fmtInt(g.planner_calls), "num");
      cell(tr, fmtInt(g.failures), "num");
      cell(tr, fmtInt(g.refusals), "num");
      cell(tr, fmtMs(g.validate_ms.p95), "num");
      cell(tr, fmtMs(g.plan_ms.p95), "num");
      cell(tr, fmtMs(g.time_saved_ms), "num");
      return tr;
    });
    fillTable($("robots-table"), rows, 9, "No robot planned in this window");
  }

  // The newest seed jobs, and any other seed job that planned in the window: state and progress
  // from /v1/seed-jobs, requests, hit rate and failures in the window from the stats groups.
  function renderSeedJobs(stats, jobs) {
    const groups = new Map(stats.groups.filter((g) => g.requester === "seed_job").map((g) => [g.key, g]));
    const rows = jobs.items.map((job) => {
      const key = seedJobKey(job.job_id);
      const g = groups.get(key);
      groups.delete(key);
      const tr = document.createElement("tr");
      cell(tr, job.name ? `#${job.job_id} ${job.name}` : `#${job.job_id}`).title = key;
      cell(tr, job.state, `state-${job.state}`).title = job.message || "";
      cell(tr, `${fmtInt(job.done)} / ${fmtInt(job.total)} (${fmtPct(job.total ? job.done / job.total : null)})`, "num");
      seedJobStats(tr, g);
      return tr;
    });
    for (const g of groups.values()) { // older than the jobs listed
      const tr = document.createElement("tr");
      cell(tr, g.key);
      cell(tr, "–");
      cell(tr, "–", "num");
      seedJobStats(tr, g);
      rows.push(tr);
    }
    fillTable($("seed-jobs-table"), rows, 6, "No seed jobs");
  }

  function seedJobStats(tr, g) {
    cell(tr, fmtInt(g ? g.requests : 0), "num");
    cell(tr, fmtPct(g ? g.hit_rate : null), "num");
    cell(tr, fmtInt(g ? g.failures : 0), "num");
  }

  function renderTop(top) {
    const rows = top.map((t) => {
      const tr = document.createElement("tr");
      trajectoryLink(cell(tr, ""), t.trajectory_id);
      modelCell(cell(tr, ""), t.model_id);
      cell(tr, t.source);
      cell(tr, fmtInt(t.hits), "num");
      cell(tr, fmtInt(t.failures), "num");
      cell(tr, fmtDateTime(t.last_used_at));
      return tr;
    });
    fillTable($("top-table"), rows, 6, "The cache is empty");
  }

  // Who asked: a robot by its id, or a seed job by its number (its events' robot id is a key).
  function requesterCell(tr, e) {
    if (e.requester !== "seed_job") return cell(tr, e.robot_id);
    const td = cell(tr, `seed job #${e.robot_id.replace(/^seed-job-/, "")}`, "seed-job");
    td.title = `${e.robot_id}: planned in simulation`;
    return td;
  }

  function eventRow(e, withTrajectory) {
    const tr = document.createElement("tr");
    cell(tr, fmtTime(e.created_at)).title = fmtDateTime(e.created_at);
    requesterCell(tr, e);
    cell(tr, e.status, `status-${e.status}`).title = e.error || "";
    // the goal: a state (joint) or a link's pose; none for events recorded before the kind was
    if (withTrajectory) cell(tr, e.goal_kind || "–", "goal-kind");
    cell(tr, e.source || "–");
    if (withTrajectory) trajectoryLink(cell(tr, ""), e.trajectory_id);
    const tried = cell(tr, String(e.candidates_tried), "num");
    const rejected = (e.rejections || []).length;
    if (rejected) tried.title = `${rejected} rejected: ${e.rejections.map((r) => `#${r.trajectory_id} ${r.status}`).join(", ")}`;
    if (!withTrajectory) cell(tr, fmtMs(e.validate_ms), "num");
    cell(tr, fmtMs(e.total_ms), "num");
    if (withTrajectory) viewLink(cell(tr, ""), e, rejected);
    return tr;
  }

  // Open the event in the 3D view (view3d.js follows #view3d's data-show).
  function viewLink(td, e, rejected) {
    if (e.trajectory_id === null && !rejected) { td.textContent = "–"; return; }
    const a = document.createElement("a");
    a.className = rejected ? "view3d-link rejected" : "view3d-link";
    a.textContent = rejected ? `why (${rejected})` : "view";
    a.title = rejected ? "the rejected candidates, at their first failing sample" : "the trajectory in 3D";
    a.dataset.event = String(e.event_id);
    a.addEventListener("click", () => {
      pickEvent(e.event_id);
      $("view3d").scrollIntoView({ block: "nearest" });
    });
    td.appendChild(a);
  }

  function show3d(what) {
    const view = $("view3d");
    if (view && view.dataset.show !== what) view.dataset.show = what;
  }

  function renderEvents(page) {
    fillTable($("events-table"), page.items.map((e) => eventRow(e, true)), 9, "No plan events yet");
  }

  // Plans refused without an answer (a 4xx of a plan route): who, when, and why.
  function renderRefusals(page) {
    const rows = page.items.map((e) => {
      const tr = document.createElement("tr");
      cell(tr, fmtTime(e.created_at)).title = fmtDateTime(e.created_at);
      requesterCell(tr, e);
      modelCell(cell(tr, ""), e.model_id);
      cell(tr, e.error || "–", "reason");
      return tr;
    });
    fillTable($("refusals-table"), rows, 4, "No refused plans");
  }

  // Pick a trajectory: the inspector, the usage history and the 3D view show it.
  function pickTrajectory(id) {
    state.awaitingView = false;
    history.replaceState(null, "", `#trajectory=${id}`);
    return inspect(id);
  }

  // Pick a plan event: the 3D view opens it and reports the trajectory it shows (`follow3d`).
  function pickEvent(eventId) {
    state.awaitingView = true;
    history.replaceState(null, "", `#event=${eventId}`);
    show3d(`event:${eventId}`);
  }

  // The 3D view shows trajectory `trajectory` (null: none, or it failed): the others follow.
  function follow3d(trajectory) {
    state.awaitingView = false;
    if (trajectory === null || trajectory === undefined) return;
    state.viewed = trajectory;
    if (state.inspected !== trajectory) inspect(trajectory).catch((err) => setStatus(String(err.message || err), true));
  }

  async function inspect(id) {
    state.inspected = id;
    $("inspect-id").value = String(id);
    $("usage-title").textContent = `Usage history of trajectory #${id}`;
    const svg = $("chart-joints");
    let detail;
    try {
      detail = await api(`/v1/trajectories/${id}`);
    } catch (err) {
      if (err instanceof AuthNeeded) throw err;
      $("inspect-meta").textContent = String(err.message || err);
      Charts.empty(svg, `Trajectory ${id} is not available`);
      fillTable($("usage-table"), [], 7, "–");
      return;
    }
    const info = await modelInfo(detail.model_id).catch(() => null);
    const names = info ? info.stateNames : null;
    const states = detail.states;
    // x: how far along the path each key state is (cumulative state-space distance, 0…1).
    const along = [0];
    for (let i = 1; i < states.length; i += 1) {
      const step = Math.hypot(...states[i].map((v, d) => v - states[i - 1][d]));
      along.push(along[i - 1] + step);
    }
    const length = along[along.length - 1] || 1;
    const series = states[0].map((_, d) => ({
      name: names ? names[d] : `q${d}`,
      color: Charts.PALETTE[d % Charts.PALETTE.length],
      points: states.map((s, i) => [along[i] / length, s[d]]),
    }));
    Charts.line(svg, series, {
      xMin: 0, xMax: 1, legend: true,
      xFormat: (v) => `${Math.round(v * 100)} %`,
      yFormat: (v) => v.toFixed(2),
    });
    const meta = $("inspect-meta");
    meta.textContent =
      `#${detail.trajectory_id} · ${detail.source} · ${states.length} key states · ${fmtInt(detail.hits)} hits, ` +
      `${fmtInt(detail.failures)} failures · model `;
    meta.appendChild(modelCell(document.createElement("span"), detail.model_id));
    meta.appendChild(document.createTextNode(" (x: share of the path, y: rad or m)"));
    fillTable($("usage-table"), detail.usage_history.map((e) => eventRow(e, false)), 7, "Not used yet");
    if (state.viewed !== id) { // a newly picked trajectory: the 3D view follows it
      state.viewed = id;
      show3d(`trajectory:${id}`);
    }
  }

  // --- refresh loop -------------------------------------------------------------------------

  function setStatus(text, error) {
    $("status").textContent = text;
    $("status").className = error ? "error" : "";
  }

  async function refresh() {
    if (state.busy) {
      state.again = true; // asked for while a refresh runs (e.g. a new window): run once more
      return;
    }
    state.busy = true;
    clearTimeout(state.timer);
    const window_ = $("window").value;
    try {
      const [stats, top, events, jobs, refusals] = await Promise.all([
        api(`/v1/stats?window=${encodeURIComponent(window_)}&group_by=robot`),
        api("/v1/stats/top-trajectories?limit=10"),
        api("/v1/plan-events?limit=15"),
        api(`/v1/seed-jobs?limit=${SEED_JOBS_LISTED}`),
        api(`/v1/plan-events?status=refused&limit=${REFUSALS_LISTED}`),
      ]);
      await knowModels([...top.map((t) => t.model_id), ...refusals.items.map((e) => e.model_id)]);
      state.stats = stats;
      renderKpis(stats);
      renderCharts(stats);
      renderRobots(stats);
      renderSeedJobs(stats, jobs);
      renderTop(top);
      renderEvents(events);
      renderRefusals(refusals);
      // nothing picked yet: the most used trajectory (unless a picked event's is on its way)
      const first = state.awaitingView || !top.length ? null : top[0].trajectory_id;
      const pick = state.inspected || first;
      if (pick !== null) await inspect(pick);
      else Charts.empty($("chart-joints"), state.awaitingView ? "Opening the plan event…" : "Pick a trajectory");
      state.refreshes += 1;
      document.body.dataset.state = "ready";
      document.body.dataset.refreshes = String(state.refreshes);
      document.body.dataset.window = stats.window;
      const charted = stats.series.length ? ` from ${fmtDateTime(stats.series[0].start)}` : "";
      setStatus(`Updated ${fmtTime(new Date().toISOString())} UTC · charted${charted} in buckets of ${fmtSpan(stats.bucket_s)}`);
    } catch (err) {
      if (err instanceof AuthNeeded) {
        $("key-panel").hidden = false;
        $("key-message").textContent = err.message;
        setStatus("An admin key is needed", true);
        document.body.dataset.state = "auth";
        state.busy = false;
        return; // no auto-refresh until a key is given
      }
      setStatus(`Refresh failed: ${err.message || err}`, true);
      document.body.dataset.state = "error";
    } finally {
      state.busy = false;
    }
    if (state.again) {
      state.again = false;
      refresh();
      return;
    }
    schedule();
  }

  function schedule() {
    clearTimeout(state.timer);
    const every = Number($("refresh-every").value);
    if (every > 0) state.timer = setTimeout(refresh, every * 1000);
  }

  // A deep link: `#event=N` (view3d.js opens it, once loaded) or `#trajectory=N`; true if any.
  function followHash() {
    const event = /event=(\d+)/.exec(location.hash);
    const trajectory = /trajectory=(\d+)/.exec(location.hash);
    if (event) {
      state.inspected = null;
      pickEvent(Number(event[1]));
    } else if (trajectory) {
      state.awaitingView = false;
      state.inspected = Number(trajectory[1]);
    }
    return Boolean(event || trajectory);
  }

  function start() {
    $("refresh").addEventListener("click", refresh);
    $("window").addEventListener("change", refresh);
    $("refresh-every").addEventListener("change", schedule);
    $("latency-metric").addEventListener("change", () => state.stats && renderLatency(state.stats));
    $("key-button").addEventListener("click", () => { $("key-panel").hidden = !$("key-panel").hidden; });
    $("key-form").addEventListener("submit", (ev) => {
      ev.preventDefault();
      const key = $("key-input").value.trim();
      if (key) sessionStorage.setItem(KEY_STORAGE, key);
      $("key-input").value = "";
      $("key-panel").hidden = true;
      refresh();
    });
    $("key-clear").addEventListener("click", () => {
      sessionStorage.removeItem(KEY_STORAGE);
      $("key-message").textContent = "Key forgotten";
    });
    $("inspect-form").addEventListener("submit", (ev) => {
      ev.preventDefault();
      const id = parseInt($("inspect-id").value, 10);
      if (id > 0) pickTrajectory(id).catch((err) => setStatus(String(err.message || err), true));
    });
    $("view3d").addEventListener("view3d-shown", (ev) => follow3d(ev.detail.trajectory));
    window.addEventListener("hashchange", () => {
      if (followHash()) refresh();
    });
    followHash();
    refresh();
  }

  start();
})();
