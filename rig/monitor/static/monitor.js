// rig monitor: draws the state the server put in the page (#initial-state), then polls /api/state (incremental:
// ?since=N). No library, no request elsewhere.
"use strict";
(() => {
  const POLL_MS = 1000;
  const MAX_EVENTS = 200;
  const token = new URLSearchParams(location.search).get("token");
  const st = { generation: null, next: 0, points: new Map(), ill: [], lamp: [], warm: [], events: [],
               chosen: null, lastSeries: null, eventsShown: -1 };
  const $ = (id) => document.getElementById(id);
  const VIRIDIS = [[68, 1, 84], [59, 82, 139], [33, 145, 140], [94, 201, 98], [253, 231, 37]];
  const INK = "#1d2330", GRID = "#e5e7eb", MUTED = "#6b7280", BLUE = "#2563eb", ORANGE = "#ea580c";
  const RUNS = [ORANGE, "#7c3aed", "#0d9488", "#be123c", "#4d7c0f"];   // E⊥ of run 1, 2, … (a resume starts one)
  const runColour = (r) => RUNS[(r || 0) % RUNS.length];

  function reset() {
    st.points.clear(); st.ill = []; st.lamp = []; st.warm = []; st.events = []; st.next = 0; st.eventsShown = -1;
  }

  function apply(changes) {
    for (const c of changes) {
      if (c.k === "p") { st.points.set(c.id, c); if (c.s !== null) st.lastSeries = c.s; }
      else if (c.k === "d") st.points.delete(c.id);
      else if (c.k === "e") st.ill.push(c);
      else if (c.k === "l") st.lamp.push(c);
      else if (c.k === "w") st.warm.push(c);
      else if (c.k === "ev") st.events.push(c);
    }
    if (st.events.length > MAX_EVENTS) st.events.splice(0, st.events.length - MAX_EVENTS);
  }

  function take(s) {
    if (s.generation !== st.generation) { reset(); st.generation = s.generation; }
    apply(s.changes);
    st.next = s.next;
    render(s);
  }

  async function poll() {
    const q = new URLSearchParams({ since: String(st.next) });
    if (st.generation) q.set("generation", st.generation);
    if (token) q.set("token", token);
    try {
      const r = await fetch("api/state?" + q.toString(), { cache: "no-store" });
      if (!r.ok) throw new Error(r.status + ": " + (await r.text()));
      take(await r.json());
      $("connection").textContent = "";
    } catch (e) {
      $("connection").textContent = "· no answer from the monitor (" + e.message + "); retrying";
    }
    setTimeout(poll, POLL_MS);
  }

  // -- formatting ------------------------------------------------------------------------------
  function duration(s) {
    if (s === null || s === undefined || !isFinite(s)) return "–";
    s = Math.max(0, Math.round(s));
    const h = Math.floor(s / 3600), m = Math.floor((s % 3600) / 60), sec = s % 60;
    return h + ":" + String(m).padStart(2, "0") + ":" + String(sec).padStart(2, "0");
  }
  const num = (x, d = 3) => (x === null || x === undefined ? "–" : Number(x).toPrecision(d));
  const angle = (x) => String(Number(Number(x).toFixed(1)));          // 70 → "70", 22.5 → "22.5"
  function text(id, value) { const el = $(id); if (el.textContent !== value) el.textContent = value; }
  function cell(tr, value, cls) {
    const td = document.createElement("td"); td.textContent = value; if (cls) td.className = cls; tr.appendChild(td);
    return td;
  }

  // -- the page ----------------------------------------------------------------------------------
  function render(s) {
    text("campaign", s.campaign ? "rig monitor — " + s.campaign : "rig monitor");
    text("sample", s.sample ? "sample " + s.sample : "");
    text("where", [s.folder, s.rig ? "rig file: " + s.rig + (s.simulated ? ", simulated devices" : "") : null,
                   s.software ? "software: rig " + s.software : null].filter(Boolean).join(" · "));
    $("state").dataset.phase = s.phase;
    text("phase", s.phase);
    text("detail", s.warmup ? warmupWords(s.warmup) : (s.detail || ""));
    const w = s.warnings || [];        // lines skipped and files not read (docs/monitor.md): said, never hidden
    text("warnings", w.length ? "Not followed: " + w.slice(-3).join(" · ") +
         (s.bad_lines > 3 ? " (" + s.bad_lines + " lines skipped in all)" : "") : "");
    const p = s.progress;
    text("done", String(p.done));
    text("to-measure", p.to_measure === null ? "?" : String(p.to_measure));
    $("bar").style.width = p.to_measure ? Math.min(100, (100 * p.done) / p.to_measure).toFixed(1) + "%" : "0";
    text("progress-note", (p.to_measure ? ((100 * p.done) / p.to_measure).toFixed(0) + " % · " : "") +
         p.skipped + " skipped by the plan · " + p.pending + " waiting for their E⊥ bracket");
    text("eta-wall", s.eta.wall_s !== null ? duration(s.eta.wall_s) : s.eta.rig_s !== null ? "≈ " + duration(s.eta.rig_s) : "–");
    text("eta-rig", s.eta.rig_s !== null ? duration(s.eta.rig_s) + " of rig time" +
         (s.eta.wall_per_rig ? " · " + num(s.eta.wall_per_rig, 2) + " wall s per rig s"
          : s.warmup ? ", the warm-up's rest included" : "") : "");
    text("rig-time", duration(s.rig_time_s));
    text("started", s.created_utc ? "started " + s.created_utc.replace("T", " ") : "");
    if (s.last_utc) {
      const ago = (Date.parse(s.now_utc) - Date.parse(s.last_utc)) / 1000;
      text("last-write", ago < 90 ? Math.max(0, ago).toFixed(0) + " s ago" : duration(ago) + " ago");
      text("last-utc", s.last_utc.replace("T", " "));
    }
    picker(s);
    const series = chosenSeries();
    const inc = incidence(s, series);
    drawPlane(series, inc);
    drawPolar(series, inc);
    drawIlluminance();
    drawLamp();
    events();
    tables(s);
  }

  // The warm-up in words: elapsed, expected (and from where), the last check's reading and change, the rest.
  function warmupWords(w) {
    const parts = ["lamp on " + duration(w.elapsed_s) + (w.expected_s !== null ? " of ≈ " + duration(w.expected_s) +
                   " expected" : "")];
    if (w.last) parts.push("E⊥ " + num(w.last.lx, 5) + " lx, changed " + (100 * w.last.change).toFixed(2) +
                           " % per check (steady below " + (100 * w.last.stable_below).toFixed(2) + " %)");
    if (w.left_s !== null) parts.push("≈ " + duration(w.left_s) + " left");
    return parts.join(" · ") + (w.source ? " — expected from " + w.source : "");
  }

  function chosenSeries() { return st.chosen !== null ? st.chosen : st.lastSeries; }

  function incidence(s, series) {
    const planned = (s.series || []).find((x) => x.index === series);
    if (planned) return { ti: planned.theta_i_deg, pi: planned.phi_i_deg };
    const pts = [...st.points.values()].filter((q) => q.s === series);
    return pts.length ? { ti: pts[0].ti, pi: pts[0].pi } : null;
  }

  function picker(s) {
    const indices = (s.series && s.series.length) ? s.series.map((x) => x.index)
      : [...new Set([...st.points.values()].map((q) => q.s))].sort((a, b) => a - b);
    const el = $("series-picker");
    const key = indices.join(",") + "|" + chosenSeries() + "|" + st.chosen;
    if (el.dataset.key === key) return;
    el.dataset.key = key;
    el.replaceChildren();
    const add = (label, value, title) => {
      const b = document.createElement("button");
      b.textContent = label; b.title = title;
      b.className = (value === st.chosen) ? "on" : "";
      b.addEventListener("click", () => { st.chosen = value; el.dataset.key = ""; render(s); });
      el.appendChild(b);
    };
    add("follow", null, "the series being measured");
    for (const i of indices) {
      const x = (s.series || []).find((y) => y.index === i);
      add(x ? "θi " + angle(x.theta_i_deg) + "° φi " + angle(x.phi_i_deg) + "°" : "s" + i, i, "series " + i);
    }
  }

  // -- canvas helpers ------------------------------------------------------------------------------
  function surface(canvas) {
    if (!canvas.dataset.aspect) canvas.dataset.aspect = String(canvas.height / canvas.width);
    const dpr = window.devicePixelRatio || 1;
    const w = canvas.clientWidth || canvas.width, h = Math.round(w * Number(canvas.dataset.aspect));
    if (canvas.width !== Math.round(w * dpr)) { canvas.width = Math.round(w * dpr); canvas.height = Math.round(h * dpr); }
    const ctx = canvas.getContext("2d");
    ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
    ctx.clearRect(0, 0, w, h);
    ctx.font = "11px system-ui, sans-serif";
    return { ctx, w, h };
  }

  function niceTicks(lo, hi, n) {
    const span = hi - lo || 1, raw = span / n, mag = Math.pow(10, Math.floor(Math.log10(raw)));
    const step = [1, 2, 5, 10].map((k) => k * mag).find((k) => k >= raw);
    const out = [];
    for (let v = Math.ceil(lo / step) * step; v <= hi + step * 1e-9; v += step) out.push(Number(v.toPrecision(12)));
    return out;
  }

  function range(values, pad) {
    let lo = Math.min(...values), hi = Math.max(...values);
    if (!isFinite(lo)) return [0, 1];
    if (hi - lo < 1e-12) { lo -= Math.abs(lo) * 0.01 + 1e-9; hi += Math.abs(hi) * 0.01 + 1e-9; }
    const p = (hi - lo) * pad;
    return [lo - p, hi + p];
  }

  // Ticks of a log10 axis: decades, and 2 and 5 (every mantissa over less than a decade) on a short one.
  function logTicks(lo, hi) {
    const span = hi - lo;
    if (span < 0.6) return niceTicks(Math.pow(10, lo), Math.pow(10, hi), 4).filter((x) => x > 0).map(Math.log10);
    const mantissas = span > 4 ? [1] : span > 1.2 ? [1, 2, 5] : [1, 2, 3, 4, 5, 6, 7, 8, 9];
    const out = [];
    for (let k = Math.floor(lo); k <= Math.ceil(hi); k++) {
      for (const m of mantissas) { const v = k + Math.log10(m); if (v >= lo && v <= hi) out.push(v); }
    }
    return span > 4 ? out.filter((v, i) => i % Math.ceil(out.length / 6) === 0) : out;
  }
  function label10(v) {
    const x = Math.pow(10, v);
    return x >= 1e4 || x < 1e-3 ? x.toExponential(1) : String(Number(x.toPrecision(3)));
  }

  // Axes in a box; returns value→pixel maps. log: y is log10 of the values (ticks at decades).
  function axes(ctx, box, xr, yr, o) {
    const X = (v) => box.x + ((v - xr[0]) / (xr[1] - xr[0])) * box.w;
    const Y = (v) => box.y + box.h - ((v - yr[0]) / (yr[1] - yr[0])) * box.h;
    ctx.strokeStyle = GRID; ctx.fillStyle = MUTED; ctx.lineWidth = 1;
    const xt = o.xticks || niceTicks(xr[0], xr[1], 6);
    ctx.textAlign = "center"; ctx.textBaseline = "top";
    for (const v of xt) {
      ctx.beginPath(); ctx.moveTo(X(v), box.y); ctx.lineTo(X(v), box.y + box.h); ctx.stroke();
      ctx.fillText(o.xfmt ? o.xfmt(v) : String(v), X(v), box.y + box.h + 3);
    }
    const yt = o.log ? logTicks(yr[0], yr[1]) : niceTicks(yr[0], yr[1], 6);
    ctx.textAlign = o.right ? "left" : "right"; ctx.textBaseline = "middle";
    for (const v of yt) {
      if (!o.right) { ctx.beginPath(); ctx.moveTo(box.x, Y(v)); ctx.lineTo(box.x + box.w, Y(v)); ctx.stroke(); }
      const label = o.log ? label10(v) : String(v);
      ctx.fillText(label, o.right ? box.x + box.w + 4 : box.x - 4, Y(v));
    }
    ctx.strokeStyle = "#9ca3af"; ctx.strokeRect(box.x, box.y, box.w, box.h);
    ctx.fillStyle = INK; ctx.textAlign = "center"; ctx.textBaseline = "bottom";
    if (o.xlabel) ctx.fillText(o.xlabel, box.x + box.w / 2, box.y + box.h + 30);
    if (o.ylabel) {
      ctx.save(); ctx.translate(o.right ? box.x + box.w + 44 : box.x - 40, box.y + box.h / 2);
      ctx.rotate(-Math.PI / 2); ctx.textBaseline = o.right ? "top" : "bottom"; ctx.fillText(o.ylabel, 0, 0); ctx.restore();
    }
    return { X, Y };
  }

  function empty(ctx, w, h, message) {
    ctx.fillStyle = MUTED; ctx.textAlign = "center"; ctx.textBaseline = "middle";
    ctx.fillText(message, w / 2, h / 2);
  }

  function colour(t) {
    t = Math.min(1, Math.max(0, t)) * (VIRIDIS.length - 1);
    const i = Math.min(VIRIDIS.length - 2, Math.floor(t)), f = t - i;
    const c = VIRIDIS[i].map((a, k) => Math.round(a + (VIRIDIS[i + 1][k] - a) * f));
    return "rgb(" + c.join(",") + ")";
  }

  function dot(ctx, x, y, r, fill, stroke) {
    ctx.beginPath(); ctx.arc(x, y, r, 0, 2 * Math.PI); ctx.fillStyle = fill; ctx.fill();
    if (stroke) { ctx.strokeStyle = stroke; ctx.lineWidth = 0.8; ctx.stroke(); }
  }

  // A legend at (x, y): a marker (a ring, or a dot) and a label per entry, on one row.
  function legend(ctx, x, y, entries, ring) {
    ctx.textAlign = "left"; ctx.textBaseline = "middle"; ctx.lineWidth = 1.5;
    for (const [c, label, ownRing] of entries) {
      if (ring || ownRing) { ctx.strokeStyle = c; ctx.beginPath(); ctx.arc(x + 6, y + 6, 5, 0, 2 * Math.PI); ctx.stroke(); }
      else dot(ctx, x + 6, y + 6, 3, c);
      ctx.fillStyle = INK; ctx.fillText(label, x + 15, y + 6);
      x += 22 + ctx.measureText(label).width;
    }
  }

  // Separate runs (a resume starts one): a dotted line where each later run's first reading of any kind is
  // (the lamp switched on, a warm-up check, E⊥).
  function runStarts(ctx, box, X) {
    const first = new Map();
    for (const q of st.lamp.concat(st.warm, st.ill)) {
      if (q.t !== null && q.r && !(first.get(q.r) <= q.t)) first.set(q.r, q.t);
    }
    ctx.save(); ctx.setLineDash([2, 3]); ctx.strokeStyle = MUTED; ctx.fillStyle = MUTED;
    ctx.textAlign = "left"; ctx.textBaseline = "top";
    for (const t of first.values()) {
      if (X(t) < box.x || X(t) > box.x + box.w) continue;
      ctx.beginPath(); ctx.moveTo(X(t), box.y); ctx.lineTo(X(t), box.y + box.h); ctx.stroke();
      ctx.fillText("resumed", X(t) + 3, box.y + 2);
    }
    ctx.restore();
  }

  // Least-squares slope of E⊥ against rig time, relative to the mean, per hour; null with < 2 times.
  function trend(pts) {
    if (pts.length < 2) return null;
    const mt = pts.reduce((a, q) => a + q.t, 0) / pts.length, my = pts.reduce((a, q) => a + q.lx, 0) / pts.length;
    let sxy = 0, sxx = 0;
    for (const q of pts) { sxy += (q.t - mt) * (q.lx - my); sxx += (q.t - mt) * (q.t - mt); }
    return sxx > 0 ? { slope: sxy / sxx, mt, my, perHour: (3600 * sxy) / sxx / my } : null;
  }

  // -- the plots --------------------------------------------------------------------------------
  function drawPlane(series, inc) {
    const canvas = $("plane"), { ctx, w, h } = surface(canvas);
    const pts = [...st.points.values()].filter((q) => q.s === series && q.x !== null && q.f > 0);
    canvas.dataset.drawn = String(pts.length);
    const box = { x: 56, y: 10, w: w - 72, h: h - 52 };
    const ys = pts.map((q) => Math.log10(q.f));
    const yr = pts.length ? range(ys, 0.12) : [-2, 1];
    const { X, Y } = axes(ctx, box, [-90, 90], yr, { log: true, xticks: [-90, -60, -30, 0, 30, 60, 90],
      xlabel: "signed viewing angle θo in the plane of incidence [°]", ylabel: "f_r [1/sr]" });
    ctx.fillStyle = "rgba(37,99,235,0.05)"; ctx.fillRect(box.x, box.y, box.w / 2, box.h);
    ctx.fillStyle = "rgba(234,88,12,0.05)"; ctx.fillRect(box.x + box.w / 2, box.y, box.w / 2, box.h);
    if (inc && inc.ti >= 1) {
      ctx.setLineDash([4, 3]); ctx.lineWidth = 1;
      for (const [v, c, label] of [[inc.ti, ORANGE, "retro"], [-inc.ti, BLUE, "mirror"]]) {
        ctx.strokeStyle = c; ctx.beginPath(); ctx.moveTo(X(v), box.y); ctx.lineTo(X(v), box.y + box.h); ctx.stroke();
        ctx.fillStyle = c; ctx.textAlign = "center"; ctx.textBaseline = "top"; ctx.fillText(label, X(v), box.y + 2);
      }
      ctx.setLineDash([]);
    }
    if (!pts.length) { empty(ctx, w, h, series === null ? "no point yet" : "no view in the plane yet"); return; }
    pts.sort((a, b) => a.x - b.x);
    ctx.strokeStyle = "#9ca3af"; ctx.lineWidth = 1;
    for (const q of pts) {
      if (q.u > 0) {
        const lo = Math.log10(Math.max(q.f - q.u, q.f * 1e-3)), hi = Math.log10(q.f + q.u);
        ctx.beginPath(); ctx.moveTo(X(q.x), Y(lo)); ctx.lineTo(X(q.x), Y(hi)); ctx.stroke();
      }
    }
    ctx.strokeStyle = "rgba(37,99,235,0.5)"; ctx.beginPath();
    pts.forEach((q, i) => (i ? ctx.lineTo(X(q.x), Y(Math.log10(q.f))) : ctx.moveTo(X(q.x), Y(Math.log10(q.f)))));
    ctx.stroke();
    for (const q of pts) dot(ctx, X(q.x), Y(Math.log10(q.f)), 3.5, BLUE, "#fff");
    const note = pts.length + " views in the plane" + (inc ? " · θi = " + num(inc.ti, 3) + "°" : "");
    ctx.textAlign = "left"; ctx.textBaseline = "bottom"; ctx.lineWidth = 3; ctx.strokeStyle = "rgba(255,255,255,.9)";
    ctx.strokeText(note, box.x + 6, box.y + box.h - 4); ctx.fillStyle = INK; ctx.fillText(note, box.x + 6, box.y + box.h - 4);
  }

  function drawPolar(series, inc) {
    const canvas = $("polar"), { ctx, w, h } = surface(canvas);
    const pts = [...st.points.values()].filter((q) => q.s === series && q.f > 0);
    canvas.dataset.drawn = String(pts.length);
    // φo labels outside the circle, the θo rings named in a corner: no label sits under a point.
    const R = Math.min(w - 140, h - 44) / 2, cx = 34 + R, cy = h / 2;
    ctx.strokeStyle = GRID; ctx.lineWidth = 1;
    for (const t of [30, 60, 90]) { ctx.beginPath(); ctx.arc(cx, cy, (R * t) / 90, 0, 2 * Math.PI); ctx.stroke(); }
    for (let a = 0; a < 360; a += 90) {
      const r = (a * Math.PI) / 180;
      ctx.beginPath(); ctx.moveTo(cx, cy); ctx.lineTo(cx + R * Math.cos(r), cy - R * Math.sin(r)); ctx.stroke();
    }
    ctx.fillStyle = MUTED;
    for (const [label, x, y, align, base] of [["φo 0°", cx + R + 4, cy, "left", "middle"],
        ["90°", cx, cy - R - 3, "center", "bottom"], ["180°", cx - R - 4, cy, "right", "middle"],
        ["270°", cx, cy + R + 3, "center", "top"]]) {
      ctx.textAlign = align; ctx.textBaseline = base; ctx.fillText(label, x, y);
    }
    legend(ctx, 4, 4, [[ORANGE, "lamp (θi, φi)"], [BLUE, "mirror"]], true);
    ctx.fillStyle = MUTED; ctx.textAlign = "left"; ctx.textBaseline = "bottom";
    ctx.fillText("rings: θo 30°, 60°, 90°", 4, h - 2);                  // outside the circle: under no point
    const at = (t, p) => [cx + (R * t) / 90 * Math.cos((p * Math.PI) / 180), cy - (R * t) / 90 * Math.sin((p * Math.PI) / 180)];
    if (inc) {
      const [lx, ly] = at(inc.ti, inc.pi), [mx, my] = at(inc.ti, inc.pi + 180);
      ctx.strokeStyle = ORANGE; ctx.lineWidth = 1.5; ctx.beginPath(); ctx.arc(lx, ly, 6, 0, 2 * Math.PI); ctx.stroke();
      ctx.strokeStyle = BLUE; ctx.beginPath(); ctx.arc(mx, my, 6, 0, 2 * Math.PI); ctx.stroke();
    }
    if (!pts.length) { empty(ctx, w, h, "no point yet"); return; }
    const logs = pts.map((q) => Math.log10(q.f)), lo = Math.min(...logs), hi = Math.max(...logs);
    const t = (v) => (hi > lo ? (v - lo) / (hi - lo) : 0.5);
    pts.sort((a, b) => a.f - b.f);
    for (const q of pts) { const [x, y] = at(q.to, q.po); dot(ctx, x, y, 4.5, colour(t(Math.log10(q.f))), "rgba(0,0,0,.35)"); }

    const bx = w - 64, by = 22, bh = h - 46;
    for (let i = 0; i < bh; i++) { ctx.fillStyle = colour(1 - i / bh); ctx.fillRect(bx, by + i, 12, 1.5); }
    ctx.strokeStyle = "#9ca3af"; ctx.strokeRect(bx, by, 12, bh);
    ctx.fillStyle = INK; ctx.textAlign = "left"; ctx.textBaseline = "middle";
    ctx.fillText(num(Math.pow(10, hi), 2), bx + 15, by); ctx.fillText(num(Math.pow(10, lo), 2), bx + 15, by + bh);
    ctx.textBaseline = "bottom"; ctx.fillText("f_r [1/sr]", bx - 10, by - 4);
  }

  function timeTicks(lo, hi) {
    const unit = hi > 7200 ? 3600 : hi > 120 ? 60 : 1;
    return { ticks: niceTicks(lo / unit, hi / unit, 6).map((v) => v * unit),
             fmt: (v) => String(Number((v / unit).toPrecision(6))), label: "rig time [" + { 3600: "h", 60: "min", 1: "s" }[unit] + "]" };
  }

  // E⊥ readings (± u) and the warm-up's checks on the campaign's rig-time axis; each run its own line, colour
  // and least-squares trend (a resume may follow a night with the lamp off: no line is drawn across it).
  function drawIlluminance() {
    const canvas = $("illuminance"), { ctx, w, h } = surface(canvas);
    const pts = st.ill.filter((q) => q.t !== null && q.lx !== null);
    const warm = st.warm.filter((q) => q.t !== null && q.lx !== null);
    canvas.dataset.drawn = String(pts.length + warm.length);
    if (!pts.length && !warm.length) { empty(ctx, w, h, "no E⊥ reading yet"); return; }
    const all = pts.concat(warm);
    const xr = range(all.map((q) => q.t), 0.03);
    const yr = range(all.flatMap((q) => [q.lx - (q.u || 0), q.lx + (q.u || 0)]), 0.1);
    const tt = timeTicks(xr[0], xr[1]);
    const box = { x: 64, y: 22, w: w - 84, h: h - 62 };
    const { X, Y } = axes(ctx, box, xr, yr, { xticks: tt.ticks, xfmt: tt.fmt, xlabel: tt.label, ylabel: "E⊥ [lx]" });
    runStarts(ctx, box, X);
    ctx.strokeStyle = "#9ca3af";
    for (const q of pts) if (q.u) { ctx.beginPath(); ctx.moveTo(X(q.t), Y(q.lx - q.u)); ctx.lineTo(X(q.t), Y(q.lx + q.u)); ctx.stroke(); }
    for (const q of warm) { ctx.strokeStyle = MUTED; ctx.lineWidth = 1; ctx.beginPath(); ctx.arc(X(q.t), Y(q.lx), 3, 0, 2 * Math.PI); ctx.stroke(); }
    const runs = [...new Set(pts.map((q) => q.r || 0))];
    const entries = [];
    for (const r of runs) {
      const run = pts.filter((q) => (q.r || 0) === r), c = runColour(r);
      ctx.strokeStyle = c; ctx.globalAlpha = 0.5; ctx.lineWidth = 1; ctx.beginPath();
      run.forEach((q, i) => (i ? ctx.lineTo(X(q.t), Y(q.lx)) : ctx.moveTo(X(q.t), Y(q.lx)))); ctx.stroke();
      ctx.globalAlpha = 1;
      for (const q of run) dot(ctx, X(q.t), Y(q.lx), 2.5, c);
      const fit = trend(run);
      if (fit) {
        const t0 = run[0].t, t1 = run[run.length - 1].t;
        ctx.setLineDash([5, 3]); ctx.strokeStyle = c; ctx.beginPath();
        ctx.moveTo(X(t0), Y(fit.my + fit.slope * (t0 - fit.mt))); ctx.lineTo(X(t1), Y(fit.my + fit.slope * (t1 - fit.mt)));
        ctx.stroke(); ctx.setLineDash([]);
      }
      entries.push([c, (runs.length > 1 ? "run " + (r + 1) + " " : "E⊥ ") +
                    (fit ? "trend " + (100 * fit.perHour >= 0 ? "+" : "") + (100 * fit.perHour).toFixed(2) + " %/h" : "")]);
    }
    if (warm.length) entries.push([MUTED, "warm-up checks", true]);
    legend(ctx, box.x, 2, entries, false);
  }

  function drawLamp() {
    const canvas = $("lamp"), { ctx, w, h } = surface(canvas);
    const pts = st.lamp.filter((q) => q.t !== null);
    const cur = pts.filter((q) => q.i !== null), volt = pts.filter((q) => q.v !== null);
    canvas.dataset.drawn = String(cur.length + volt.length);
    if (!pts.length) { empty(ctx, w, h, "no lamp reading yet"); return; }
    const xr = range(pts.map((q) => q.t), 0.08), tt = timeTicks(xr[0], xr[1]);
    const box = { x: 62, y: 22, w: w - 120, h: h - 62 };
    const opts = { xticks: tt.ticks, xfmt: tt.fmt, xlabel: tt.label };
    if (cur.length) {
      // currents in the lower part of the box, voltages in the upper: a reading of each at one time never overlaps
      const [lo, hi] = range(cur.map((q) => q.i), 0.2);
      const { X, Y } = axes(ctx, box, xr, [lo, hi + (hi - lo)], { ...opts, ylabel: "current [A]" });
      runStarts(ctx, box, X);
      for (const q of cur) dot(ctx, X(q.t), Y(q.i), 3.5, BLUE);
    }
    legend(ctx, box.x, 2, [[BLUE, "current"], [ORANGE, "voltage"]], false);
    if (volt.length) {
      const [lo, hi] = range(volt.map((q) => q.v), 0.2);
      const { X, Y } = axes(ctx, box, xr, [lo - (hi - lo), hi],
                            { ...opts, right: true, xticks: [], ylabel: "voltage [V]" });
      ctx.fillStyle = ORANGE;
      for (const q of volt) { ctx.fillRect(X(q.t) - 3, Y(q.v) - 3, 6, 6); }
    }
  }

  // -- the tables -------------------------------------------------------------------------------
  function events() {
    if (st.eventsShown === st.next) return;
    st.eventsShown = st.next;
    const body = $("events").tBodies[0];
    body.replaceChildren();
    for (const e of st.events.slice().reverse()) {
      const tr = document.createElement("tr"); tr.className = e.event;
      cell(tr, e.utc ? e.utc.slice(11, 19) : "", "num");
      cell(tr, e.t === null ? "" : duration(e.t), "num");
      cell(tr, e.event);
      cell(tr, e.text);
      body.appendChild(tr);
    }
  }

  function fill(id, rows) {
    const body = $(id).tBodies[0];
    body.replaceChildren();
    if (!rows.length) { const tr = document.createElement("tr"); cell(tr, "none yet").className = "muted"; body.appendChild(tr); }
    for (const [a, b, title] of rows) {
      const tr = document.createElement("tr"); if (title) tr.title = title;
      cell(tr, a); cell(tr, b, "num"); body.appendChild(tr);
    }
  }

  function tables(s) {
    fill("budget", (s.budget || []).map((b) => [b.component.replace("u_rel_", ""),
      (100 * b.median_u_rel).toPrecision(2) + " %", b.meaning + " (p95 " + (100 * b.p95_u_rel).toPrecision(2) + " %)"]));
    fill("skipped", (s.skipped || []).map((k) => [k.reason, String(k.count), k.meaning]));
    fill("flags", Object.entries(s.flags || {}).map(([f, n]) => [f, String(n)]));
  }

  const initial = document.getElementById("initial-state");      // the server's first paint, drawn at once
  if (initial) { try { take(JSON.parse(initial.textContent)); } catch (e) { /* the poll below draws it */ } }
  setTimeout(poll, initial ? POLL_MS : 0);
})();
