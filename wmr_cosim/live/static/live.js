// The live view's page (docs/live.md): the stream of rows drawn with uPlot, one time plot per unit of the
// variables chosen, the event table's entries as markers and in a table, the requirements' verdicts as the
// online monitor gives them, the path of [live] xy with the task's goals, and the controls of the API.
"use strict";
(function () {
  const token = new URLSearchParams(location.search).get("token");
  const q = token ? "?token=" + encodeURIComponent(token) : "";
  const $ = (id) => document.getElementById(id);
  const MAX_ROWS = 20000;          // rows kept: past this, every other one is dropped (the plot keeps its span)
  const FRAME_MS = 50;             // the plots are redrawn at most this often (20 a second) when rows came in
  const DEFAULT_SHOWN = 4;         // variables shown at first (those of the XY path, else the first ones)
  const COLORS = ["#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2", "#17becf",
                  "#7f7f7f", "#bcbd22"];

  let columns = [], units = [], data = [], shown = new Set(), settable = [], events = [], state = null;
  let charts = [], dirty = false, ended = false, xy = null, needCharts = false;
  // what the tests read: rows received, plot redraws, the time of the last row, the points of the path, the
  // wall time of the last redraw [ms] and of the longest
  const stats = window.liveStats = {rows: 0, draws: 0, lastTime: null, xyPoints: 0, charts: 0, redrawMs: 0,
                                    maxRedrawMs: 0};

  const unitLabel = (u) => (u ? u : "no unit");
  const fmt = (x, d) => (x == null ? "-" : (Math.abs(x) >= 1e5 || (Math.abs(x) < 1e-3 && x !== 0)
                                               ? x.toExponential(d || 3) : x.toFixed(d || 4)));

  async function post(path, body) {
    try {
      const r = await fetch("api/" + path + q, {method: "POST", headers: {"Content-Type": "application/json"},
                                                 body: body === undefined ? "" : JSON.stringify(body)});
      const doc = await r.json();
      $("error").textContent = r.ok ? "" : doc.error;
      if (r.ok) showState(doc);
    } catch (e) {
      $("error").textContent = String(e);
    }
  }

  // ---------------------------------------------------------------- the state
  function showState(s) {
    state = s;
    const finished = s.mode === "finished";
    const running = s.status === "running";
    const rtf = s.real_time_factor == null ? "-" : s.real_time_factor.toPrecision(3) + "x";
    const pace = s.rate ? s.rate + "x" : "as fast as possible";
    const what = running ? (s.paused ? "paused" : "running") : s.status + (s.message ? ": " + s.message : "");
    $("status").innerHTML = "";
    $("status").append(`t = `, Object.assign(document.createElement("b"), {id: "time", textContent: fmt(s.time)}),
      ` of ${s.stop_time} s, step ${s.steps ?? "-"} of ${s.n_steps ?? "-"} · ${what}` +
      (finished ? "" : ` · real-time factor ${rtf} (pace: ${pace})`));
    $("progress").firstElementChild.style.width = (s.stop_time ? 100 * s.time / s.stop_time : 0) + "%";
    if (finished) {
      $("title").textContent = "wmr-cosim view: " + s.folder;
      $("controls").hidden = true;
    }
    if (!running) for (const b of document.querySelectorAll("#controls button")) b.disabled = true;
    if (String(s.rate) !== $("rate").value && document.activeElement !== $("rate")) $("rate").value = String(s.rate);
    if (!settable.length && s.settable && s.settable.length) setSettable(s.settable);
    if (s.requirements) showRequirements(s.requirements);
    if (s.xy) setXY(s.xy);
  }

  function setSettable(list) {
    settable = list;
    const sel = $("setvar");
    sel.innerHTML = "";
    for (const v of settable) {
      const o = document.createElement("option");
      o.value = v.name;
      o.textContent = v.name + (v.unit ? ` [${v.unit}]` : "");
      sel.appendChild(o);
    }
    sel.onchange = showSettable;
    showSettable();
  }

  function showSettable() {
    const v = settable.find((s) => s.name === $("setvar").value);
    if (!v) return;
    $("setunit").textContent = v.unit ? " " + v.unit + " " : " ";
    const bound = (x) => (x != null && Math.abs(x) < 1e300 ? x : null);   // (a float's largest: no bound)
    const lo = bound(v.min), hi = bound(v.max);
    const range = lo != null || hi != null ? `min ${lo ?? "-inf"}, max ${hi ?? "inf"}` : "no min or max";
    $("setinfo").textContent = `${v.causality}, ${v.type}, ${range}, start ${v.start ?? "-"}`;
    $("setval").placeholder = v.start == null ? "" : String(v.start);
  }

  function showRequirements(reqs) {
    const body = $("requirements").tBodies[0];
    body.innerHTML = "";
    for (const r of reqs) {
      const tr = body.insertRow();
      tr.title = r.formula + (r.description ? "\n" + r.description : "");
      tr.insertCell().textContent = r.name;
      const v = tr.insertCell();
      v.textContent = r.verdict;
      v.className = r.verdict;
      const rob = tr.insertCell();
      rob.className = "num";
      rob.textContent = r.robustness == null ? "-" : fmt(r.robustness) + (r.unit ? " " + r.unit : "");
      for (const k of ["at", "decided_at"]) {
        const c = tr.insertCell();
        c.className = "num";
        c.textContent = r[k] == null ? "-" : fmt(r[k], 3);
      }
    }
  }

  // ---------------------------------------------------------------- the event table
  function addEvents(list) {
    const body = $("events").tBodies[0];
    for (const e of list) {
      events.push(e);
      const tr = body.insertRow();
      tr.className = "source-" + (e.source || "scenario");
      const cells = [fmt(e.time, 4), e.variable ?? e.event ?? "", e.action ?? e.kind ?? "",
                     e.value == null ? "" : String(e.value), e.source || e.kind || ""];
      for (const c of cells) tr.insertCell().textContent = c;
    }
    for (const c of charts) c.redraw(false, false);
  }

  function eventMarkers() {   // a uPlot plugin: each event of the table as a vertical line at its time
    return {hooks: {draw: [(u) => {
      const ctx = u.ctx, top = u.bbox.top, h = u.bbox.height;
      ctx.save();
      ctx.lineWidth = 1;
      for (const e of events) {
        if (typeof e.time !== "number") continue;
        const x = u.valToPos(e.time, "x", true);
        if (x < u.bbox.left || x > u.bbox.left + u.bbox.width) continue;
        ctx.strokeStyle = e.source === "live" ? "#d62728" : "#888";
        ctx.setLineDash([4, 3]);
        ctx.beginPath(); ctx.moveTo(x, top); ctx.lineTo(x, top + h); ctx.stroke();
      }
      ctx.restore();
    }]}};
  }

  // ---------------------------------------------------------------- the variables and the time plots
  function setColumns(msg) {
    columns = msg.columns; units = msg.units;
    data = columns.map(() => []);
    const byUnit = new Map();
    columns.forEach((c, i) => {
      if (i === 0) return;
      const u = unitLabel(units[i]);
      if (!byUnit.has(u)) byUnit.set(u, []);
      byUnit.get(u).push(i);
    });
    const want = xy ? [columns.indexOf(xy.x), columns.indexOf(xy.y)].filter((i) => i > 0) : [];
    for (let i = 1; i < columns.length && want.length < DEFAULT_SHOWN; i++) if (!want.includes(i)) want.push(i);
    shown = new Set(want);
    const box = $("vars");
    box.innerHTML = "";
    for (const [u, idx] of [...byUnit.entries()].sort()) {
      box.appendChild(Object.assign(document.createElement("h3"), {textContent: `[${u}]`}));
      for (const i of idx) {
        const l = document.createElement("label"), b = document.createElement("input");
        b.type = "checkbox"; b.checked = shown.has(i); b.dataset.column = columns[i];
        b.onchange = () => { b.checked ? shown.add(i) : shown.delete(i); buildCharts(); };
        l.title = columns[i] + (units[i] ? ` [${units[i]}]` : "");
        l.append(b, " " + columns[i]);
        box.appendChild(l);
      }
    }
    $("filter").oninput = () => {
      const f = $("filter").value.toLowerCase();
      for (const l of box.querySelectorAll("label")) l.hidden = f && !l.title.toLowerCase().includes(f);
    };
    buildCharts();
  }

  function buildCharts() {
    for (const c of charts) c.destroy();
    charts = [];
    if (!data.length || !data[0].length) { needCharts = true; return; }   // (uPlot needs a row to scale its axes)
    needCharts = false;
    const groups = new Map();
    for (const i of [...shown].sort((a, b) => a - b)) {
      const u = unitLabel(units[i]);
      if (!groups.has(u)) groups.set(u, []);
      groups.get(u).push(i);
    }
    const box = $("charts");
    box.innerHTML = "";
    const width = Math.max(300, box.clientWidth - 2);
    let k = 0;
    for (const [u, idx] of groups) {
      const div = document.createElement("div");
      div.className = "chart"; div.dataset.unit = u;
      box.appendChild(div);
      const opts = {
        width, height: groups.size > 2 ? 180 : 240,
        scales: {x: {time: false}},
        axes: [{label: "time [s]"}, {label: u === "no unit" ? "" : `[${u}]`, size: 70,
                                     values: (self, splits) => splits.map((v) => (v == null ? "" : +v.toPrecision(4)))}],
        series: [{label: "t [s]"}].concat(idx.map((i) => ({label: columns[i], stroke: COLORS[k++ % COLORS.length],
                                                            width: 1.5, points: {show: false}}))),
        legend: {live: true},
        cursor: {drag: {x: true, y: false}},
        plugins: [eventMarkers()],
        hooks: charts.length === 0 ? {draw: [() => { stats.draws++; }]} : {},
      };
      const chart = new uPlot(opts, [data[0]].concat(idx.map((i) => data[i])), div);
      chart.columns = idx;
      charts.push(chart);
    }
    stats.charts = charts.length;
  }

  function addRow(row) {
    for (let i = 0; i < row.length; i++) data[i].push(row[i]);
    stats.rows++;
    stats.lastTime = row[0];
    if (data[0].length > MAX_ROWS) {   // every other row dropped, the last kept
      for (let i = 0; i < data.length; i++) data[i] = data[i].filter((_, j) => j % 2 === 1 || j === data[i].length - 1);
    }
    dirty = true;
  }

  function redraw() {
    if (!dirty) return;
    const t0 = performance.now();
    dirty = false;
    if (needCharts) buildCharts();
    for (const c of charts) c.setData([data[0]].concat(c.columns.map((i) => data[i])));
    drawXY();
    stats.redrawMs = performance.now() - t0;
    stats.maxRedrawMs = Math.max(stats.maxRedrawMs, stats.redrawMs);
  }

  // ---------------------------------------------------------------- the XY path
  function setXY(s) {
    const first = xy === null;
    xy = s;
    $("xypanel").hidden = false;
    $("xytitle").textContent = `path: ${s.x} [${s.units[0] || ""}] against ${s.y} [${s.units[1] || ""}]` +
      (s.goals && s.goals.length ? ", goal" + (s.goals.length > 1 ? "s" : "") + " marked" : "");
    if (first && columns.length) setColumns({columns, units});
    drawXY();
  }

  function drawXY() {
    if (!xy) return;
    const cv = $("xy"), dpr = window.devicePixelRatio || 1;
    const W = cv.clientWidth, H = cv.clientHeight;
    if (!W || !H) return;
    if (cv.width !== W * dpr) { cv.width = W * dpr; cv.height = H * dpr; }
    const g = cv.getContext("2d");
    g.setTransform(dpr, 0, 0, dpr, 0, 0);
    g.clearRect(0, 0, W, H);
    const xi = columns.indexOf(xy.x), yi = columns.indexOf(xy.y);
    if (xi < 0 || yi < 0) return;
    const X = data[xi], Y = data[yi], goals = xy.goals || [];
    let x0 = Infinity, x1 = -Infinity, y0 = Infinity, y1 = -Infinity;
    const take = (x, y) => { if (x == null || y == null) return; x0 = Math.min(x0, x); x1 = Math.max(x1, x);
                                                                 y0 = Math.min(y0, y); y1 = Math.max(y1, y); };
    for (let j = 0; j < X.length; j++) take(X[j], Y[j]);
    for (const [gx, gy] of goals) take(gx, gy);
    if (!isFinite(x0)) return;
    const span = Math.max(x1 - x0, y1 - y0, 1e-6) * 1.1, cx = (x0 + x1) / 2, cy = (y0 + y1) / 2, m = 40;
    const scale = Math.min(W - 2 * m, H - 2 * m) / span;   // one metre is as long on both axes
    const px = (x) => W / 2 + (x - cx) * scale, py = (y) => H / 2 - (y - cy) * scale;
    g.strokeStyle = "#ccc"; g.strokeRect(px(cx - span / 2), py(cy + span / 2), span * scale, span * scale);
    g.fillStyle = "#555"; g.font = "11px sans-serif";
    g.fillText(`${xy.x} [${xy.units[0] || ""}]: ${fmt(cx - span / 2, 3)} to ${fmt(cx + span / 2, 3)}`, m, H - 6);
    g.save(); g.translate(12, H - m); g.rotate(-Math.PI / 2);
    g.fillText(`${xy.y} [${xy.units[1] || ""}]: ${fmt(cy - span / 2, 3)} to ${fmt(cy + span / 2, 3)}`, 0, 0);
    g.restore();
    g.strokeStyle = "#1f77b4"; g.lineWidth = 2; g.beginPath();
    let n = 0;
    for (let j = 0; j < X.length; j++) {
      if (X[j] == null || Y[j] == null) continue;
      n++ === 0 ? g.moveTo(px(X[j]), py(Y[j])) : g.lineTo(px(X[j]), py(Y[j]));
    }
    g.stroke();
    stats.xyPoints = n;
    for (const [gx, gy] of goals) {   // the goal: a ring and a cross
      g.strokeStyle = "#2ca02c"; g.lineWidth = 2;
      g.beginPath(); g.arc(px(gx), py(gy), 8, 0, 2 * Math.PI); g.stroke();
      g.beginPath(); g.moveTo(px(gx) - 12, py(gy)); g.lineTo(px(gx) + 12, py(gy));
      g.moveTo(px(gx), py(gy) - 12); g.lineTo(px(gx), py(gy) + 12); g.stroke();
      g.fillStyle = "#2ca02c"; g.fillText(`goal (${gx}, ${gy})`, px(gx) + 12, py(gy) - 10);
    }
    if (n) {   // where the point is now
      const j = X.length - 1;
      g.fillStyle = "#d62728"; g.beginPath(); g.arc(px(X[j]), py(Y[j]), 5, 0, 2 * Math.PI); g.fill();
    }
  }

  // ---------------------------------------------------------------- the stream
  function connect() {
    const ws = new WebSocket((location.protocol === "https:" ? "wss://" : "ws://") + location.host + "/api/stream" + q);
    ws.onmessage = (e) => {
      const msg = JSON.parse(e.data);
      if (msg.type === "columns") {
        if (msg.state && msg.state.xy) xy = msg.state.xy;
        setColumns(msg);
        if (msg.row) addRow(msg.row);
        showState(msg.state);
        addEvents(msg.events || []);
      } else if (msg.type === "row" || msg.type === "rows") {
        if (msg.row) addRow(msg.row);
        for (const r of msg.rows || []) addRow(r);
        if (msg.events) addEvents(msg.events);
        if (msg.requirements) showRequirements(msg.requirements);
      } else if (msg.type === "end") { ended = true; showState(msg.state); dirty = true; redraw(); }
    };
    ws.onclose = () => {
      if (state && state.mode !== "finished") $("status").append(" (the run has ended: the server is gone)");
    };
    setInterval(redraw, FRAME_MS);
    setInterval(async () => {   // the state (time, pace, real-time factor) four times a second
      if (ws.readyState !== WebSocket.OPEN || ended || (state && state.mode === "finished")) return;
      try { const r = await fetch("api/state" + q); if (r.ok) showState(await r.json()); } catch (e) { /* gone */ }
    }, 250);
  }

  $("pause").onclick = () => post("pause");
  $("resume").onclick = () => post("resume");
  $("stop").onclick = () => post("stop");
  $("step").onclick = () => post("step", {steps: parseInt($("steps").value, 10) || 1});
  $("rate").onchange = () => post("rate", {factor: parseFloat($("rate").value)});
  $("set").onclick = () => {
    const v = settable.find((s) => s.name === $("setvar").value), text = $("setval").value.trim();
    let value = text;
    if (v && v.type === "Boolean") value = text === "true" || text === "1";
    else if (v && v.type !== "String" && text !== "" && !isNaN(Number(text))) value = Number(text);
    post("set", {variable: $("setvar").value, value: value});
  };
  window.addEventListener("resize", () => { if (columns.length) buildCharts(); });
  connect();
})();
