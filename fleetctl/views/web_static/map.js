// fleetctl web map: draws the run in ENU metres (x east, y north; SVG y = -north) from the
// server-sent events of /events (hello, plan, frame). No external assets; map tiles only when the
// server was given --tiles (an XYZ template) and the mission origin.
"use strict";
(function () {
  const SVG = "http://www.w3.org/2000/svg";
  const TRAIL_POINTS = 400, TRAIL_STEP = 0.5, ON_DECK = new Set(["on_deck", "loaded", "unknown"]);
  const $ = (id) => document.getElementById(id);
  const view = { minE: Infinity, maxE: -Infinity, minN: Infinity, maxN: -Infinity, key: "" };
  let config = {}, plan = null, trails = {}, reached = new Set(), currentStops = {};

  function el(tag, attrs, parent) {
    const e = document.createElementNS(SVG, tag);
    for (const k in attrs) e.setAttribute(k, attrs[k]);
    if (parent) parent.appendChild(e);
    return e;
  }
  const fmt = (x, nd) => (x === null || x === undefined) ? "–" : Number(x).toFixed(nd === undefined ? 1 : nd);
  const tplus = (t) => (t === null || t === undefined) ? "T+–" : "T+" + fmt(t) + "s";

  // -- extent: grows to hold everything ever shown, so the picture does not jump ---------------
  function include(e, n) {
    if (e === null || n === null || e === undefined || n === undefined) return;
    view.minE = Math.min(view.minE, e); view.maxE = Math.max(view.maxE, e);
    view.minN = Math.min(view.minN, n); view.maxN = Math.max(view.maxN, n);
  }
  function unit() { return Math.max(view.maxE - view.minE, view.maxN - view.minN, 20) / 120; }
  function applyExtent() {
    if (!isFinite(view.minE)) return false;
    const pad = Math.max(view.maxE - view.minE, view.maxN - view.minN, 20) * 0.06;
    const box = [view.minE - pad, -(view.maxN + pad), view.maxE - view.minE + 2 * pad, view.maxN - view.minN + 2 * pad];
    const key = box.map((v) => v.toFixed(1)).join(" ");
    if (key === view.key) return false;
    view.key = key; view.box = box;
    $("map").setAttribute("viewBox", key);
    drawGrid(); drawTiles();
    return true;
  }

  function drawGrid() {
    const g = $("grid"); g.innerHTML = ""; g.setAttribute("class", "grid");
    const [x, y, w, h] = view.box, u = unit();
    const steps = [5, 10, 20, 25, 50, 100, 200, 250, 500, 1000, 2000, 5000];
    const step = steps.find((s) => Math.max(w, h) / s <= 12) || 10000;
    for (let e = Math.ceil(x / step) * step; e <= x + w; e += step) {
      el("line", { x1: e, y1: y, x2: e, y2: y + h }, g);
      el("text", { x: e + u * 0.3, y: y + h - u * 0.5, "font-size": u * 1.6 }, g).textContent = e + " E";
    }
    for (let n = Math.ceil(-(y + h) / step) * step; n <= -y; n += step) {
      el("line", { x1: x, y1: -n, x2: x + w, y2: -n }, g);
      el("text", { x: x + u * 0.3, y: -n - u * 0.3, "font-size": u * 1.6 }, g).textContent = n + " N";
    }
  }

  // -- optional XYZ tiles (Web Mercator), placed with the server's metres per degree ------------
  function drawTiles() {
    const g = $("tiles"); g.innerHTML = "";
    if (!config.tiles || !config.origin) return;
    const o = config.origin, m = config.m_per_deg, [x, y, w, h] = view.box;
    const lon = (e) => o.lon + e / m.lon, lat = (n) => o.lat + n / m.lat;
    const tileX = (lo, z) => (lo + 180) / 360 * 2 ** z;
    const tileY = (la, z) => { const r = la * Math.PI / 180; return (1 - Math.log(Math.tan(r) + 1 / Math.cos(r)) / Math.PI) / 2 * 2 ** z; };
    const lonOf = (tx, z) => tx / 2 ** z * 360 - 180;
    const latOf = (ty, z) => { const k = Math.PI - 2 * Math.PI * ty / 2 ** z; return 180 / Math.PI * Math.atan(0.5 * (Math.exp(k) - Math.exp(-k))); };
    const size = Math.max(w, h), tileM = (z) => 40075016 * Math.cos(o.lat * Math.PI / 180) / 2 ** z;
    let z = 1; while (z < 20 && tileM(z + 1) > size / 4) z++;
    const x0 = Math.floor(tileX(lon(x), z)), x1 = Math.floor(tileX(lon(x + w), z));
    const y0 = Math.floor(tileY(lat(-y), z)), y1 = Math.floor(tileY(lat(-(y + h)), z));
    for (let tx = x0; tx <= x1; tx++) for (let ty = y0; ty <= y1; ty++) {
      const e0 = (lonOf(tx, z) - o.lon) * m.lon, e1 = (lonOf(tx + 1, z) - o.lon) * m.lon;
      const n0 = (latOf(ty, z) - o.lat) * m.lat, n1 = (latOf(ty + 1, z) - o.lat) * m.lat;
      const href = config.tiles.replace("{z}", z).replace("{x}", tx).replace("{y}", ty);
      el("image", { href: href, x: e0, y: -n0, width: e1 - e0, height: n0 - n1, preserveAspectRatio: "none", opacity: 0.6 }, g);
    }
  }

  // -- the plan layer: every team's route, stops and rover paths; every task --------------------
  // a team's colour (null for a one-team run: the style sheet's colours, as always)
  const paint = (colour, prop) => colour ? `${prop}: ${colour}` : "";
  function drawPlan(p) {
    plan = p;
    const teams = p.teams || [];
    for (const t of p.tasks) include(t.e, t.n);
    for (const l of teams) for (const r of l.route) include(r[0], r[1]);
    applyExtent();
    const u = unit();
    const route = $("route"); route.innerHTML = "";
    const paths = $("paths"); paths.innerHTML = "";
    const stops = $("stops"); stops.innerHTML = "";
    for (const l of teams) {
      const team = l.team || "";
      if (l.route.length > 1) el("polyline", { class: "route", "data-route": team, style: paint(l.colour, "stroke"), points: l.route.map((q) => q[0] + "," + -q[1]).join(" ") }, route);
      for (const r of l.paths) el("polyline", { class: "path", "data-team": team, points: r.path.map((q) => q[0] + "," + -q[1]).join(" ") }, paths);
      for (const s of l.stops) {
        const g = el("g", { class: "stop", "data-stop": s.k, "data-team": team, transform: `translate(${s.e},${-s.n})` }, stops);
        el("circle", { r: u * 2.2, style: paint(l.colour, "stroke") }, g);
        el("text", { x: -u * 0.6, y: u * 4.4, "font-size": u * 1.8, fill: l.colour || "#4a90d9" }, g).textContent = s.k;
      }
    }
    const colours = {};
    for (const l of teams) colours[l.team] = l.colour;
    const tasks = $("tasks"); tasks.innerHTML = "";
    for (const t of p.tasks) {
      const g = el("g", { class: "task-mark", "data-task": t.id, "data-team": t.team || "", transform: `translate(${t.e},${-t.n})` }, tasks);
      el("rect", { class: "task", x: -u, y: -u, width: 2 * u, height: 2 * u, transform: "rotate(45)", style: paint(colours[t.team], "stroke") }, g);
      el("text", { x: u * 1.6, y: -u * 0.9, "font-size": u * 1.7 }, g).textContent = t.id;
    }
    markStops();
  }

  function markStops() {
    for (const g of $("stops").children) g.classList.toggle("current", Number(g.dataset.stop) === currentStops[g.dataset.team]);
    for (const g of $("tasks").children) g.querySelector("rect").classList.toggle("reached", reached.has(g.dataset.task));
  }

  // -- a long operation: each task's work (done / duration) on its marker; the sorties out -------
  function drawWork(g, w) {
    const u = unit();
    let bar = g.querySelector(".work");
    if (!w) {
      if (bar) bar.remove();
      g.classList.remove("working", "done");
      for (const k of ["worked", "duration", "rover", "progress"]) delete g.dataset[k];
      return;
    }
    if (!bar) {
      bar = el("g", { class: "work" }, g);
      el("rect", { class: "work-bg", x: -2 * u, y: u * 1.8, width: 4 * u, height: u * 0.7 }, bar);
      el("rect", { class: "work-done", x: -2 * u, y: u * 1.8, width: 0, height: u * 0.7 }, bar);
      el("text", { class: "work-text", x: -2 * u, y: u * 4.2, "font-size": u * 1.4 }, bar);
    }
    const [done, dur, rover, finished] = w;
    const frac = dur > 0 ? Math.min(1, done / dur) : (finished ? 1 : 0);
    bar.querySelector(".work-done").setAttribute("width", (4 * u * frac).toFixed(3));
    bar.querySelector(".work-text").textContent = `${fmt(done)}/${fmt(dur)} s` + (rover && !finished ? ` ${rover}` : "");
    Object.assign(g.dataset, { worked: fmt(done), duration: fmt(dur), rover: rover || "", progress: frac.toFixed(3) });
    g.classList.toggle("done", !!finished);
    g.classList.toggle("working", !finished && done > 0);
  }
  function drawOperation(op, vehicles) {
    for (const g of $("tasks").children) drawWork(g, op ? op.tasks[g.dataset.task] : undefined);
    const box = $("sorties"); box.innerHTML = "";
    if (!op || !plan) return;
    const at = {}, pos = {};
    for (const t of plan.tasks) at[t.id] = t;
    for (const v of vehicles) pos[v.id] = v;
    for (const s of op.out || []) {  // its rover, then its tasks not done yet
      const v = pos[s.rover], left = s.tasks.filter((t) => at[t] && !(op.tasks[t] && op.tasks[t][3]));
      const pts = (v && v.e !== null ? [[v.e, v.n]] : []).concat(left.map((t) => [at[t].e, at[t].n]));
      const line = el("polyline", { class: "sortie " + s.status, "data-sortie": s.sortie, "data-rover": s.rover,
        "data-tasks": left.join(" "), points: pts.map((q) => q[0] + "," + -q[1]).join(" ") }, box);
      el("title", {}, line).textContent = `sortie ${s.sortie}: ${s.rover} (${s.status}) ${s.tasks.join(", ")}`;
    }
    for (const s of op.ahead || []) {  // not launched yet: its launch stop, its tasks, its pick-up stop
      const pts = [s.launch].concat(s.tasks.filter((t) => at[t]).map((t) => [at[t].e, at[t].n]))
        .concat(s.pickup ? [s.pickup] : []);
      const line = el("polyline", { class: "sortie planned", "data-sortie": s.sortie, "data-rover": s.rover,
        "data-tasks": s.tasks.join(" "), "data-in": fmt(s.in), points: pts.map((q) => q[0] + "," + -q[1]).join(" ") }, box);
      el("title", {}, line).textContent = `sortie ${s.sortie}: ${s.rover} planned, takes off in ${fmt(s.in)} s: ${s.tasks.join(", ")}`;
    }
  }

  // -- trails ----------------------------------------------------------------------------------
  function trailLine(v) {
    let line = $("trails").querySelector(`[data-trail="${v.id}"]`);
    if (!line) line = el("polyline", { class: "trail " + v.role, "data-trail": v.id, points: "" }, $("trails"));
    const style = paint(v.colour, "stroke");
    if (line.getAttribute("style") !== style) line.setAttribute("style", style);
    return line;
  }
  function addTrail(v) {
    if (v.e === null || v.n === null) return;
    if (v.role === "rover" && ON_DECK.has(v.state)) {  // riding on the carrier: its trail is the carrier's
      if (trails[v.id] && trails[v.id].length) { trails[v.id] = []; trailLine(v).setAttribute("points", ""); }
      return;
    }
    const t = trails[v.id] || (trails[v.id] = []);
    const last = t[t.length - 1];
    if (last && Math.hypot(last[0] - v.e, last[1] - v.n) < TRAIL_STEP) return;
    t.push([v.e, v.n]);
    if (t.length > TRAIL_POINTS) t.shift();
    trailLine(v).setAttribute("points", t.map((q) => q[0] + "," + -q[1]).join(" "));
  }

  // -- vehicles, list, header, events ----------------------------------------------------------
  function vehicleMark(v) {
    let g = $("vehicles").querySelector(`[data-vehicle="${v.id}"]`);
    if (g) return g;
    const u = unit();
    g = el("g", { class: "vehicle " + v.role, "data-vehicle": v.id }, $("vehicles"));
    if (v.role === "carrier") el("rect", { class: "body", x: -1.8 * u, y: -1.2 * u, width: 3.6 * u, height: 2.4 * u }, g);
    else el("circle", { class: "body", r: u * 0.9 }, g);
    if (v.colour) {  // several teams: the carrier in its team's colour, a rover ringed with it
      g.dataset.team = v.team;
      const body = g.querySelector(".body");
      if (v.role === "carrier") body.style.fill = v.colour;
      else { body.style.stroke = v.colour; body.style.strokeWidth = "2.5"; }
    }
    el("text", { x: u * 1.3, y: u * 0.6, "font-size": u * 1.6 }, g).textContent = v.id;
    if (v.role === "carrier") $("vehicles").insertBefore(g, $("vehicles").firstChild);
    return g;
  }
  function drawVehicle(v) {
    const g = vehicleMark(v);
    g.dataset.state = v.state; g.dataset.task = v.task || "";
    if (v.e !== null && v.n !== null) {
      g.dataset.e = v.e.toFixed(2); g.dataset.n = v.n.toFixed(2);
      g.setAttribute("transform", `translate(${v.e},${-v.n})`);
      g.style.display = "";
    } else g.style.display = "none";
    addTrail(v);
    if (v.role === "rover" && v.state === "on_task" && v.task) reached.add(v.task);
  }
  function row(v) {
    const tb = $("list").tBodies[0];
    let tr = tb.querySelector(`[data-row="${v.id}"]`);
    if (!tr) { tr = document.createElement("tr"); tr.dataset.row = v.id; for (let i = 0; i < 7; i++) tr.appendChild(document.createElement("td")); tb.appendChild(tr); }
    tr.style.boxShadow = v.colour ? `inset 4px 0 0 ${v.colour}` : "";
    const c = tr.children;
    c[0].textContent = v.id; c[1].textContent = v.state; c[2].textContent = v.task || "";
    c[3].textContent = fmt(v.e); c[4].textContent = fmt(v.n);
    c[5].textContent = v.battery === null ? "–" : v.battery + "%"; c[5].className = "lvl-" + v.battery_level;
    c[6].textContent = v.ttg === null ? "" : fmt(v.ttg) + "s";
    c[0].className = "lvl-" + v.link;
  }
  // several teams: one line per team under the header, in its colour
  function drawTeams(f) {
    const box = $("teams"), teams = (f.teams || []).filter((t) => t.team);
    box.hidden = !teams.length;
    box.innerHTML = "";
    for (const t of teams) {
      const s = document.createElement("span");
      s.className = "team"; s.dataset.team = t.team; s.style.color = t.colour;
      const eta = t.eta === null ? "" : ` · ETA T+${fmt(t.eta)}s (${fmt(t.ttg)} s to go)`;
      s.dataset.eta = t.eta === null ? "" : fmt(t.eta);
      s.textContent = `■ ${t.team} ${t.phase}` + (t.stops ? ` · stop ${t.stop}/${t.stops}` : "") + eta
        + (t.replans ? ` · ${t.replans} replans` : "");
      if (t.planned) {  // the phase's progress: elapsed of planned
        const bar = document.createElement("span"), done = document.createElement("i");
        bar.className = "bar"; bar.title = `${fmt(t.elapsed)} of ${fmt(t.planned)} s planned`;
        done.style.width = Math.min(100, 100 * (t.elapsed || 0) / t.planned).toFixed(1) + "%";
        done.style.background = t.colour;
        bar.appendChild(done); s.appendChild(bar);
      }
      box.appendChild(s);
    }
  }
  function drawFrame(f) {
    const colours = {};
    for (const t of f.teams || []) colours[t.team] = t.colour;
    $("mission").textContent = f.mission;
    $("phase").textContent = f.phase + (f.replans ? ` · ${f.replans} replans` : "");
    $("stop").textContent = f.stops ? `stop ${f.stop}/${f.stops}` : "";
    $("clock").textContent = tplus(f.T);
    $("ttg").textContent = f.ttg === null ? "" : `ETA T+${fmt(f.T + f.ttg)}s (${fmt(f.ttg)} s to go)`;
    const op = f.operation;
    if (op) {  // a long operation: sorties, tasks done, the tasks being worked (done / duration), its ETA
      const work = op.working.map(t => `${t} ${fmt(op.tasks[t][0])}/${fmt(op.tasks[t][1])} s`).join(", ");
      $("stop").textContent += ` · sorties ${op.sorties_out} out, ${op.sorties_back} back of ${op.sorties}`
        + ` · tasks ${op.done}/${Object.keys(op.tasks).length} done` + (work ? ` · working ${work}` : "");
      if (op.eta !== null) $("ttg").textContent = `ETA T+${fmt(op.eta)}s`;
    }
    currentStops = {};
    for (const t of f.teams || []) currentStops[t.team || ""] = t.stop;
    drawTeams(f);
    for (const v of f.vehicles) { v.colour = colours[v.team] || null; include(v.e, v.n); }
    if (applyExtent() && plan) drawPlan(plan);
    for (const v of f.vehicles) { drawVehicle(v); row(v); }
    drawOperation(op, f.vehicles);
    markStops();
    const ol = $("events"); ol.innerHTML = "";
    for (const ev of f.events.slice().reverse()) {
      const li = document.createElement("li");
      const t = document.createElement("span"); t.className = "t"; t.textContent = tplus(ev.T);
      li.appendChild(t);
      if (ev.team) { const k = document.createElement("span"); k.className = "k"; k.style.color = colours[ev.team] || ""; k.textContent = ev.team; li.appendChild(k); }
      li.appendChild(document.createTextNode(ev.text)); ol.appendChild(li);
    }
  }

  function hello(doc) {
    config = doc.config || {};
    trails = {}; $("trails").innerHTML = "";
    if (doc.trails) for (const id in doc.trails) { trails[id] = doc.trails[id].slice(-TRAIL_POINTS); for (const q of trails[id]) include(q[0], q[1]); }
    if (doc.plan) drawPlan(doc.plan);
    if (doc.frame) drawFrame(doc.frame);
    for (const id in trails) {
      const line = $("trails").querySelector(`[data-trail="${id}"]`);
      if (line) line.setAttribute("points", trails[id].map((q) => q[0] + "," + -q[1]).join(" "));
    }
  }

  function connect() {
    const link = $("link");
    // a map bound beyond loopback has a token: the page's link carries it (and set a cookie); the
    // stream is given it too
    const token = new URLSearchParams(location.search).get("token");
    const es = new EventSource(token ? "/events?token=" + encodeURIComponent(token) : "/events");
    es.addEventListener("hello", (m) => { link.textContent = "live"; link.className = "conn live"; hello(JSON.parse(m.data)); });
    es.addEventListener("plan", (m) => drawPlan(JSON.parse(m.data)));
    es.addEventListener("frame", (m) => drawFrame(JSON.parse(m.data)));
    es.onerror = () => { link.textContent = "disconnected (retrying)"; link.className = "conn lost"; };
  }
  connect();
})();
