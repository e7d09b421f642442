// report.html's viewer: draws the flight embedded in #flight-data with plain SVG (no
// network, no library) and keeps the map, the plots and the tree timeline at the time the
// slider picks.
(function () {
  "use strict";
  var D = JSON.parse(document.getElementById("flight-data").textContent);
  var NS = "http://www.w3.org/2000/svg";
  var T = D.trace, N = T.t.length, END = Math.max(D.end, 1e-6);
  var STATUS = { 1: ["RUNNING", "#f0ad4e"], 2: ["SUCCESS", "#4caf50"],
                 3: ["FAILURE", "#e53935"], 4: ["SKIPPED", "#9e9e9e"] };
  var PHASE_COLOURS = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b",
                       "#e377c2", "#7f7f7f", "#bcbd22", "#17becf", "#aec7e8", "#ffbb78"];
  var EVENT_COLOURS = { inserted: "#2e7d32", merged: "#90a4ae", updated: "#64b5f6",
                        replaced: "#ff9800", dropped: "#795548", rejected: "#bdbdbd",
                        banned: "#d50000", site_revealed: "#6a1b9a", touchdown: "#000",
                        note: "#455a64" };
  var TERMS = ["w_dist \u00b7 d / D", "w_rough \u00b7 roughness", "w_var \u00b7 uncertainty",
               "\u2212 w_size \u00b7 size / size_max", "w_verAlt \u00b7 verAlt / D"];
  var now = END;
  var cursors = [];
  var listeners = [];

  function el(tag, attrs, parent, text) {
    var e = document.createElementNS(NS, tag);
    for (var k in attrs) { if (attrs[k] !== null && attrs[k] !== undefined) e.setAttribute(k, attrs[k]); }
    if (text !== undefined) e.textContent = text;
    if (parent) parent.appendChild(e);
    return e;
  }
  function title(node, text) { el("title", {}, node, text); return node; }
  function fmt(v, d, unit) {
    return (v === null || v === undefined || isNaN(v)) ? "-" : v.toFixed(d) + (unit || "");
  }
  function esc(s) {
    return String(s).replace(/[&<>"]/g, function (c) {
      return { "&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;" }[c];
    });
  }
  // Index of the last sample at or before t (0 when t precedes them all).
  function sampleAt(t) {
    var lo = 0, hi = N - 1;
    if (N === 0) return -1;
    while (lo < hi) { var mid = (lo + hi + 1) >> 1; if (T.t[mid] <= t) lo = mid; else hi = mid - 1; }
    return lo;
  }
  function phaseAt(t) {
    var p = null;
    for (var i = 0; i < D.phases.length; i++) { if (D.phases[i][0] <= t) p = D.phases[i][1]; }
    return p;
  }
  var phaseNames = [];
  D.phases.forEach(function (p) { if (phaseNames.indexOf(p[1]) < 0) phaseNames.push(p[1]); });
  function phaseColour(name) { return PHASE_COLOURS[phaseNames.indexOf(name) % PHASE_COLOURS.length]; }

  // ------------------------------------------------------------------ header
  var S = D.summary;
  document.getElementById("outcome").textContent = S.outcome;
  document.getElementById("outcome").className = "badge " + S.outcome;
  var facts = [["mission time", fmt(S.mission_time, 1, " s")],
               ["time to land", fmt(S.time_to_land, 1, " s")],
               ["distance", fmt(S.distance, 0, " m")],
               ["battery used", fmt(S.energy && S.energy.battery_used, 1, " %")],
               ["sites", S.sites_retained + " retained, " + S.sites_verified + " verified, " +
                S.sites_banned + " banned"],
               ["touchdown error", fmt(S.touchdown_error, 2, " m")],
               ["seed", S.seed], ["world", S.world], ["detector", S.detector],
               ["autopilot", S.autopilot]];
  if (S.outcome !== "landed" && S.stop_reason) facts.push(["stopped", S.stop_reason]);
  var factsEl = document.getElementById("facts");
  facts.forEach(function (f) {
    var s = document.createElement("span");
    s.innerHTML = esc(f[0]) + ": <b>" + esc(f[1]) + "</b>";
    factsEl.appendChild(s);
  });

  // ------------------------------------------------------------------ tooltip
  var tip = document.getElementById("tip");
  function showTip(evt, html) {
    tip.innerHTML = html; tip.style.display = "block";
    var x = evt.clientX + 14, y = evt.clientY + 14;
    if (x + tip.offsetWidth > window.innerWidth) x = evt.clientX - tip.offsetWidth - 14;
    if (y + tip.offsetHeight > window.innerHeight) y = evt.clientY - tip.offsetHeight - 14;
    tip.style.left = x + "px"; tip.style.top = y + "px";
  }
  function hideTip() { tip.style.display = "none"; }

  // ------------------------------------------------------------------ map
  var MW = 560, MH = 560, W0 = D.window;
  var map = document.getElementById("map");
  map.setAttribute("width", MW); map.setAttribute("height", MH);
  function mx(x) { return (x - W0[0]) / (W0[1] - W0[0]) * MW; }
  function my(y) { return MH - (y - W0[2]) / (W0[3] - W0[2]) * MH; }
  function ms(r) { return r / (W0[1] - W0[0]) * MW; }
  el("rect", { x: 0, y: 0, width: MW, height: MH, fill: "#d9d2c3" }, map);
  if (D.map) {
    var e = D.map.extent;
    el("image", { href: D.map.href, x: mx(e[0]), y: my(e[3]), width: mx(e[1]) - mx(e[0]),
                  height: my(e[2]) - my(e[3]), preserveAspectRatio: "none" }, map);
  }
  // Grid every 10/20/50/100 m so distances can be read.
  var span = W0[1] - W0[0], step = span > 800 ? 200 : span > 400 ? 100 : span > 160 ? 50 :
    span > 80 ? 20 : 10;
  var grid = el("g", { opacity: 0.35 }, map);
  for (var gx = Math.ceil(W0[0] / step) * step; gx <= W0[1]; gx += step) {
    el("line", { x1: mx(gx), x2: mx(gx), y1: 0, y2: MH, stroke: "#fff" }, grid);
    el("text", { x: mx(gx) + 2, y: MH - 3 }, grid, gx + " m");
  }
  for (var gy = Math.ceil(W0[2] / step) * step; gy <= W0[3]; gy += step) {
    el("line", { x1: 0, x2: MW, y1: my(gy), y2: my(gy), stroke: "#fff" }, grid);
    el("text", { x: 2, y: my(gy) - 2 }, grid, gy + " m");
  }
  // Trajectory coloured by phase.
  function pointsBetween(i0, i1) {
    var pts = [];
    for (var i = i0; i <= i1 && i < N; i++) pts.push(mx(T.x[i]).toFixed(1) + "," + my(T.y[i]).toFixed(1));
    return pts.join(" ");
  }
  var phaseStarts = D.phases.map(function (p) { return p[0]; });
  for (var p = 0; p < D.phases.length; p++) {
    var i0 = sampleAt(D.phases[p][0]), i1 = p + 1 < D.phases.length ? sampleAt(phaseStarts[p + 1]) : N - 1;
    if (i1 > i0) {
      el("polyline", { points: pointsBetween(i0, i1), fill: "none", stroke: "#fff",
                       "stroke-width": 5.5, opacity: 0.7 }, map);
      title(el("polyline", { points: pointsBetween(i0, i1), fill: "none",
                             stroke: phaseColour(D.phases[p][1]), "stroke-width": 3.5 }, map),
            "phase " + D.phases[p][1]);
    }
  }
  if (D.phases.length === 0 && N > 1) {
    el("polyline", { points: pointsBetween(0, N - 1), fill: "none", stroke: "#1f77b4", "stroke-width": 2 }, map);
  }
  if (N) el("circle", { cx: mx(T.x[0]), cy: my(T.y[0]), r: 5, fill: "#1f77b4", stroke: "#fff" }, map);
  // The operating area (geofence), when the mission has one.
  if (D.geofence) {
    title(el("polygon", { points: D.geofence.map(function (v) { return mx(v[0]) + "," + my(v[1]); }).join(" "),
                          fill: "none", stroke: "#2e7d32", "stroke-width": 2,
                          "stroke-dasharray": "8 4 2 4" }, map), "geofence (operating area)");
  }
  (D.geofence_exclude || []).forEach(function (zone, i) {
    var shade = { fill: "#d50000", "fill-opacity": 0.18, stroke: "#d50000", "stroke-width": 2 };
    // A circle is {centre: [x, y], radius}; a polygon its vertices.
    if (zone.centre) {
      shade.cx = mx(zone.centre[0]); shade.cy = my(zone.centre[1]); shade.r = ms(zone.radius);
    } else {
      shade.points = zone.map(function (v) { return mx(v[0]) + "," + my(v[1]); }).join(" ");
    }
    title(el(zone.centre ? "circle" : "polygon", shade, map), "no-fly zone geofence.exclude." + i);
  });
  // Banned sites: the ban zone and a cross.
  var banEls = D.bans.map(function (b) {
    var g = el("g", {}, map);
    el("circle", { cx: mx(b.x), cy: my(b.y), r: Math.max(ms(b.r), 3), fill: "none",
                   stroke: "#d50000", "stroke-dasharray": "4 3", "stroke-width": 1.5 }, g);
    var s = 6;
    el("path", { d: "M" + (mx(b.x) - s) + "," + (my(b.y) - s) + "l" + 2 * s + "," + 2 * s +
                 "M" + (mx(b.x) - s) + "," + (my(b.y) + s) + "l" + 2 * s + "," + -2 * s,
                 stroke: "#d50000", "stroke-width": 2.5 }, g);
    title(g, "banned" + (b.site !== null ? " site " + b.site : "") +
          (b.t !== null ? " at " + fmt(b.t, 1, " s") : "") + ", ban radius " + fmt(b.r, 1, " m"));
    return g;
  });
  // Moving obstacles: each one's path, its footprint at touchdown (dashed) and where it is
  // at the slider's time (filled).
  var MV = D.moving, MOVING_COLOURS = { person: "#ef6c00", vehicle: "#7b1fa2" };
  function footprint(k, x, y, heading, attrs) {
    var kind = MV.kind[k], a = MV.half_length[k], b = MV.half_width[k], node;
    if (kind === "person") {
      node = el("circle", { cx: mx(x), cy: my(y), r: Math.max(ms(a), 2) }, map);
    } else {
      var c = Math.cos(heading), s_ = Math.sin(heading), pts = [];
      [[a, b], [-a, b], [-a, -b], [a, -b]].forEach(function (p) {
        pts.push(mx(x + c * p[0] - s_ * p[1]).toFixed(1) + "," + my(y + s_ * p[0] + c * p[1]).toFixed(1));
      });
      node = el("polygon", { points: pts.join(" ") }, map);
    }
    for (var key in attrs) node.setAttribute(key, attrs[key]);
    return node;
  }
  var movingEls = [];
  if (MV) {
    MV.kind.forEach(function (kind, k) {
      var colour = MOVING_COLOURS[kind];
      title(el("polyline", { points: MV.path[k].map(function (p) { return mx(p[0]).toFixed(1) + "," + my(p[1]).toFixed(1); }).join(" "),
                             fill: "none", stroke: colour, "stroke-width": 1.5, opacity: 0.8 }, map),
            kind + " " + k + " path");
      if (MV.touchdown) {
        var td = MV.touchdown;
        title(footprint(k, td.x[k], td.y[k], td.heading[k],
                        { fill: "none", stroke: colour, "stroke-width": 1.5, "stroke-dasharray": "3 2" }),
              kind + " " + k + " at touchdown (" + fmt(td.t, 1, " s") + ")");
      }
      movingEls.push(null);
    });
  }
  function placeMoving(t) {
    if (!MV) return;
    var i = 0;
    while (i + 1 < MV.t.length && MV.t[i + 1] <= t) i++;
    MV.kind.forEach(function (kind, k) {
      if (movingEls[k]) movingEls[k].remove();
      movingEls[k] = title(footprint(k, MV.x[i][k], MV.y[i][k], MV.heading[i][k],
                                     { fill: MOVING_COLOURS[kind], opacity: 0.6, stroke: "#000",
                                       "pointer-events": "none" }),
                           kind + " " + k + " at " + fmt(MV.t[i], 1, " s"));
    });
  }
  // Candidate sites coloured by their loss at the end of the flight.
  var losses = D.sites.map(function (s) { return s.loss; }).filter(function (v) { return v !== null; });
  var lmin = Math.min.apply(null, losses.concat([0])), lmax = Math.max.apply(null, losses.concat([1e-9]));
  function lossColour(v) {  // low loss yellow, high loss purple
    var stops = [[253, 231, 37], [94, 201, 98], [33, 145, 140], [59, 82, 139], [68, 1, 84]];
    var f = lmax > lmin ? (v - lmin) / (lmax - lmin) : 0;
    f = Math.min(1, Math.max(0, f)) * (stops.length - 1);
    var i = Math.min(stops.length - 2, Math.floor(f)), r = f - i;
    var c = stops[i].map(function (a, k) { return Math.round(a + (stops[i + 1][k] - a) * r); });
    return "rgb(" + c.join(",") + ")";
  }
  function droneAt(t) { var i = sampleAt(t); return i < 0 ? [0, 0, 0] : [T.x[i], T.y[i], T.z[i]]; }
  function terms(site, drone) {
    var w = D.weights, Dn = w.normaliser;
    var d = Math.hypot(site.x - drone[0], site.y - drone[1]);
    return [w.dist * d / Dn, w.rough * site.roughness, w.var * site.uncertainty,
            D.size_max > 0 ? -w.size * site.size / D.size_max : 0,
            w.ver_alt * site.verification_altitude / Dn, d];
  }
  function siteTip(evt, s) {
    var html = "<b>site " + s.id + "</b>" + (s.id === D.chosen ? " (chosen)" : "") +
      (s.verified ? " \u2014 verified" : "") + "<br>(" + fmt(s.x, 1) + ", " + fmt(s.y, 1) +
      ", " + fmt(s.z, 1) + ") m, seen " + s.detections + "\u00d7 from " + fmt(s.first_seen, 1) +
      " to " + fmt(s.last_seen, 1) + " s" + (s.source ? " by " + esc(s.source) : "") + "<br>";
    if (D.weights) {
      var drone = droneAt(now), k = terms(s, drone), total = 0;
      html += "loss (eq. 3.1) with the drone where it is at " + fmt(now, 1, " s") +
        " (d = " + fmt(k[5], 1, " m") + "):<table>";
      for (var i = 0; i < 5; i++) {
        total += k[i];
        html += "<tr><td>" + TERMS[i] + "</td><td class=num>" + fmt(k[i], 3) + "</td></tr>";
      }
      html += "<tr class=total><td>L</td><td class=num>" + fmt(total, 3) + "</td></tr></table>";
      html += "roughness " + fmt(s.roughness, 3) + ", uncertainty " + fmt(s.uncertainty, 3) +
        ", size " + fmt(s.size, 2) + " m (max " + fmt(D.size_max, 2) + "), verAlt " +
        fmt(s.verification_altitude, 2) + " m<br>";
    }
    html += "loss the LSM ranked it by at the end: " + fmt(s.loss, 3);
    showTip(evt, html);
  }
  // The touchdown under the sites, so that the site landed on stays hoverable.
  if (D.touchdown) {
    var td = D.touchdown, tx = mx(td.x), ty = my(td.y);
    title(el("polygon", { points: (tx - 7) + "," + (ty - 6) + " " + (tx + 7) + "," + (ty - 6) + " " + tx + "," + (ty + 7),
                          fill: td.safe === true ? "#00e676" : td.safe === false ? "#ff1744" : "#fff",
                          stroke: "#000" }, map),
          "touchdown at " + fmt(td.t, 1, " s") + ", ground " +
          (td.safe === true ? "safe" : td.safe === false ? "UNSAFE" : "not judged"));
  }
  var siteEls = D.sites.map(function (s) {
    var node;
    if (s.id === D.chosen) {
      var cx = mx(s.x), cy = my(s.y), pts = [];
      for (var i = 0; i < 10; i++) {
        var r = i % 2 ? 5 : 12, a = Math.PI / 2 + i * Math.PI / 5;
        pts.push((cx + r * Math.cos(a)).toFixed(1) + "," + (cy - r * Math.sin(a)).toFixed(1));
      }
      node = el("polygon", { points: pts.join(" "), fill: lossColour(s.loss), "class": "site" }, map);
    } else {
      node = el("circle", { cx: mx(s.x), cy: my(s.y), r: 7, fill: lossColour(s.loss), "class": "site" }, map);
    }
    if (s.verified) node.classList.add("verified");
    node.addEventListener("mousemove", function (evt) { siteTip(evt, s); });
    node.addEventListener("mouseleave", hideTip);
    return node;
  });
  // The flown part of the track and the drone: under the mouse, the sites stay hoverable.
  var flown = el("polyline", { fill: "none", stroke: "#0d47a1", "stroke-width": 1.2,
                               opacity: 0.9, "pointer-events": "none" }, map);
  var drone = el("circle", { r: 6, fill: "#fff", stroke: "#0d47a1", "stroke-width": 3,
                             "pointer-events": "none", opacity: 0.85 }, map);
  var legend = document.getElementById("map-legend");
  legend.innerHTML = phaseNames.map(function (p) {
    return "<i style='background:" + phaseColour(p) + "'></i>" + esc(p);
  }).join("") + "<br><i style='background:rgb(253,231,37);border-radius:5px'></i>low loss" +
    "<i style='background:rgb(68,1,84);border-radius:5px'></i>high loss" +
    "<i style='border:2px solid #00c853;border-radius:5px'></i>verified" +
    "<i style='border:2px dashed #d50000;border-radius:5px'></i>banned" +
    " \u2605 chosen \u25bd touchdown \u25cb drone. Hover a site for its loss terms." +
    (MV ? "<br><i style='background:#7b1fa2'></i>vehicle <i style='background:#ef6c00'></i>person" +
     " (line: path, dashed: at touchdown, filled: at the slider's time)" : "");
  listeners.push(function (t) {
    var i = sampleAt(t);
    if (i >= 0) {
      drone.setAttribute("cx", mx(T.x[i])); drone.setAttribute("cy", my(T.y[i]));
      flown.setAttribute("points", pointsBetween(0, i));
    }
    D.sites.forEach(function (s, k) { siteEls[k].classList.toggle("future", s.first_seen > t); });
    D.bans.forEach(function (b, k) { banEls[k].style.opacity = b.t !== null && b.t > t ? 0.15 : 1; });
    placeMoving(t);
  });

  // ------------------------------------------------------------------ time plots
  var TW = Math.max(520, Math.min(1100, document.getElementById("time-panel").clientWidth - 20));
  var L = 230, R = 12;
  function tx_(t) { return L + t / END * (TW - L - R); }
  function tOfX(x) { return Math.min(END, Math.max(0, (x - L) / (TW - L - R) * END)); }
  function timeSvg(id, height) {
    var svg = document.getElementById(id);
    svg.setAttribute("width", TW); svg.setAttribute("height", height);
    var c = el("line", { "class": "cursor", y1: 0, y2: height }, null);
    cursors.push(c);
    svg.addEventListener("click", function (evt) {
      var r = svg.getBoundingClientRect();
      setTime(tOfX(evt.clientX - r.left));
    });
    return { svg: svg, cursor: c };
  }
  function timeAxis(svg, y) {
    var g = el("g", { "class": "axis" }, svg);
    el("line", { x1: L, x2: TW - R, y1: y, y2: y }, g);
    var st = Math.pow(10, Math.floor(Math.log10(END / 5 || 1)));
    if (END / st > 12) st *= 5; else if (END / st > 6) st *= 2;
    for (var t = 0; t <= END + 1e-9; t += st) {
      el("line", { x1: tx_(t), x2: tx_(t), y1: y, y2: y + 4 }, g);
      el("text", { x: tx_(t), y: y + 14, "text-anchor": "middle" }, g, Math.round(t) + " s");
    }
  }
  function series(id, height, tracks, label, unit) {
    var p = timeSvg(id, height), svg = p.svg, top = 8, bottom = height - 20;
    var lo = Infinity, hi = -Infinity;
    tracks.forEach(function (tr) { tr.v.forEach(function (v) { if (v !== null) { lo = Math.min(lo, v); hi = Math.max(hi, v); } }); });
    if (!isFinite(lo)) { lo = 0; hi = 1; }
    if (hi - lo < 1) { hi += 0.5; lo -= 0.5; }
    function y(v) { return bottom - (v - lo) / (hi - lo) * (bottom - top); }
    D.phases.forEach(function (ph, k) {
      var t1 = k + 1 < D.phases.length ? D.phases[k + 1][0] : END;
      title(el("rect", { x: tx_(ph[0]), width: Math.max(0, tx_(t1) - tx_(ph[0])), y: top,
                         height: bottom - top, fill: phaseColour(ph[1]), opacity: 0.12 }, svg),
            "phase " + ph[1] + " from " + fmt(ph[0], 1, " s"));
    });
    tracks.forEach(function (tr) {
      var d = "", pen = "M";
      for (var i = 0; i < N; i++) {
        if (tr.v[i] === null) { pen = "M"; continue; }
        d += pen + tx_(T.t[i]).toFixed(1) + "," + y(tr.v[i]).toFixed(1); pen = "L";
      }
      el("path", { d: d, fill: "none", stroke: tr.colour, "stroke-width": 1.6 }, svg);
    });
    el("text", { x: 4, y: top + 10 }, svg, label);
    tracks.forEach(function (tr, k) {
      el("text", { x: 4, y: top + 24 + 13 * k, fill: tr.colour, style: "fill:" + tr.colour }, svg, tr.name);
    });
    el("text", { x: L - 4, y: top + 8, "text-anchor": "end" }, svg, fmt(hi, 0, unit));
    el("text", { x: L - 4, y: bottom, "text-anchor": "end" }, svg, fmt(lo, 0, unit));
    timeAxis(svg, bottom);
    svg.appendChild(p.cursor);
  }
  series("alt", 170, [{ v: T.z, colour: "#1565c0", name: "vehicle z" },
                      { v: T.ground, colour: "#8d6e63", name: "ground below" }],
         "altitude (m, ENU)", " m");
  series("batt", 110, [{ v: T.battery, colour: "#2e7d32", name: "battery" }], "battery (%)", " %");

  // Detector and LSM events, one row per kind of event.
  (function () {
    var kinds = [];
    D.events.forEach(function (e) { if (kinds.indexOf(e[2]) < 0) kinds.push(e[2]); });
    var rowH = 13, height = Math.max(30, kinds.length * rowH + 24);
    var p = timeSvg("events", height), svg = p.svg;
    kinds.forEach(function (k, i) {
      el("text", { x: L - 6, y: 10 + i * rowH + 9, "text-anchor": "end", "class": "lane-label" }, svg, k);
    });
    D.events.forEach(function (e) {
      var row = kinds.indexOf(e[2]);
      title(el("rect", { x: tx_(e[0]) - 1, y: 10 + row * rowH, width: 2.5, height: rowH - 3,
                         fill: EVENT_COLOURS[e[2]] || "#37474f" }, svg),
            fmt(e[0], 1, " s") + " " + e[1] + " " + e[2] + (e[3] ? ": " + e[3] : ""));
    });
    el("text", { x: 4, y: 10 }, svg, kinds.length ? "detector / LSM events" : "no detector events");
    timeAxis(svg, height - 20);
    svg.appendChild(p.cursor);
  })();

  // The tree: one lane per node, a bar per status it held.
  var lanes = D.tree.lanes, segs = D.tree.segments;
  (function () {
    var rowH = 14, height = lanes.length * rowH + 30;
    var p = timeSvg("tree", height), svg = p.svg;
    lanes.forEach(function (lane, i) {
      if (i % 2) el("rect", { x: 0, y: 4 + i * rowH, width: TW, height: rowH, fill: "#f4f6f8" }, svg);
      title(el("text", { x: 4 + lane.depth * 9, y: 4 + i * rowH + 11, "class": "lane-label" }, svg,
               lane.name.length > 30 ? lane.name.slice(0, 29) + "\u2026" : lane.name),
            lane.path + (lane.tag ? " (" + lane.tag + ")" : ""));
    });
    segs.forEach(function (s) {
      var st = STATUS[s[3]] || ["?", "#000"];
      title(el("rect", { x: tx_(s[1]), y: 4 + s[0] * rowH + 2,
                         width: Math.max(1.5, tx_(s[2]) - tx_(s[1])), height: rowH - 4,
                         fill: st[1] }, svg),
            lanes[s[0]].path + ": " + st[0] + " " + fmt(s[1], 1) + "\u2013" + fmt(s[2], 1) + " s");
    });
    timeAxis(svg, height - 22);
    svg.appendChild(p.cursor);
    var note = document.getElementById("tree-source");
    note.textContent = "from " + D.tree.source + (D.tree.truncated ? " (cut short: shown to its last transition)" : "") +
      (D.tree_note ? "; " + D.tree_note : "") + ". Running: orange, success: green, failure: red.";
  })();

  function runningAt(t) {
    var deepest = -1, names = [];
    segs.forEach(function (s) {
      if (s[3] === 1 && s[1] <= t && (t < s[2] || t >= END)) {  // at the end: still running
        var d = lanes[s[0]].depth;
        if (d > deepest) { deepest = d; names = [lanes[s[0]].name]; } else if (d === deepest) names.push(lanes[s[0]].name);
      }
    });
    return names.join(", ");
  }

  // ------------------------------------------------------------------ slider
  var slider = document.getElementById("slider");
  slider.max = END; slider.step = Math.max(END / 2000, 0.01); slider.value = END;
  var readout = document.getElementById("readout");
  function setTime(t) {
    now = Math.min(END, Math.max(0, t));
    if (Math.abs(+slider.value - now) > 1e-9) slider.value = now;
    cursors.forEach(function (c) { c.setAttribute("x1", tx_(now)); c.setAttribute("x2", tx_(now)); });
    listeners.forEach(function (f) { f(now); });
    var i = sampleAt(now);
    var z = i >= 0 ? T.z[i] : null;
    var agl = i >= 0 && T.ground[i] !== null ? T.z[i] - T.ground[i] : null;  // null: no ground
    readout.innerHTML = "<span>t <b>" + fmt(now, 1, " s") + "</b></span><span>phase <b>" +
      esc(phaseAt(now) || "-") + "</b></span><span>z <b>" + fmt(z, 1, " m") + "</b> (AGL " +
      fmt(agl, 1, " m") + ")</span><span>battery <b>" + fmt(i >= 0 ? T.battery[i] : null, 1, " %") +
      "</b></span><span>running <b>" + esc(runningAt(now) || "-") + "</b></span>";
  }
  slider.addEventListener("input", function () { setTime(+slider.value); });
  var play = document.getElementById("play"), playing = null;
  play.addEventListener("click", function () {
    if (playing !== null) { cancelAnimationFrame(playing); playing = null; play.textContent = "play"; return; }
    if (now >= END) setTime(0);
    var last = null, rate = Math.max(END / 30, 1);  // the whole flight in about 30 s
    play.textContent = "pause";
    function frame(ts) {
      if (last !== null) setTime(now + (ts - last) / 1000 * rate);
      last = ts;
      if (now >= END) { playing = null; play.textContent = "play"; return; }
      playing = requestAnimationFrame(frame);
    }
    playing = requestAnimationFrame(frame);
  });
  setTime(END);
  document.body.setAttribute("data-ready", "1");
})();
