// camplace's 3D view: draws a scene (world mm, z up) on a 2D canvas, triangles and points
// sorted far to near. Left drag orbits, right or shift drag pans, the wheel zooms.
// No WebGL: a few thousand triangles and points draw fast enough this way and every browser
// (headless ones without a GPU too) draws the same picture.
//
// The scene: `parts` (each `positions`, `triangles`, optional `edges`, `colour` #rrggbb,
// `opacity`, `kind`, `name`, and an optional `pose`: 12 numbers, the rows of a 3x4 rigid
// transform applied to its positions), optional `clouds` (each `name`, `colour`,
// `positions` and an optional `pose` as the parts'), optional `markers` (each `position`,
// `colour`, `recommended`) and an optional `view_azimuth_deg`. The inline `#scene3d` block is drawn at load when present;
// `window.camplaceView3d.show(scene)` draws another, from the same view. With `data-persist` on the canvas the
// view (orbit, pan, zoom) is kept in the session across reloads of the page.
(function () {
  "use strict";
  const canvas = document.getElementById("view3d-canvas");
  const ctx = canvas.getContext("2d");
  const reset = document.getElementById("view3d-reset");
  const persist = canvas.dataset.persist ? "view3d:" + canvas.dataset.persist : null;
  const hex = (c) => [1, 3, 5].map((i) => parseInt(c.slice(i, i + 2), 16));
  const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
  // A 3x4 row-major rigid transform applied to a point.
  const apply = (m, q) => [0, 1, 2].map((r) => m[4 * r] * q[0] + m[4 * r + 1] * q[1] + m[4 * r + 2] * q[2] + m[4 * r + 3]);
  let tris = [], edges = [], markers = [], points = [], home = null, view = null;

  function load(scene) {
    tris = [];
    edges = [];
    points = [];
    const lo = [Infinity, Infinity, Infinity];
    const hi = [-Infinity, -Infinity, -Infinity];
    const grow = (q) => {
      for (let i = 0; i < 3; i++) {
        lo[i] = Math.min(lo[i], q[i]);
        hi[i] = Math.max(hi[i], q[i]);
      }
    };
    const posed = {};
    const apexes = {};
    for (const part of scene.parts || []) {
      const rgb = hex(part.colour);
      const p = part.pose ? part.positions.map((q) => apply(part.pose, q)) : part.positions;
      for (const t of part.triangles || []) {
        tris.push({ a: p[t[0]], b: p[t[1]], c: p[t[2]], rgb: rgb, alpha: part.opacity });
      }
      for (const e of part.edges || []) edges.push({ a: p[e[0]], b: p[e[1]], rgb: rgb });
      p.forEach(grow);
      if (part.pose && p.length > 0) posed[part.name] = p[0];
      if (part.kind === "frustum") apexes[part.name] = p[0];
    }
    const counts = {};
    for (const cloud of scene.clouds || []) {
      const rgb = hex(cloud.colour);
      const p = cloud.pose ? cloud.positions.map((q) => apply(cloud.pose, q)) : cloud.positions;
      for (const q of p) points.push({ p: q, rgb: rgb });
      if (cloud.pose && p.length > 0) posed[cloud.name] = p[0];
      counts[cloud.name] = p.length;
    }
    // A measured cloud has strays: the view frames the middle 96 % of its points on each axis.
    if (points.length > 0) {
      for (let i = 0; i < 3; i++) {
        const v = points.map((q) => q.p[i]).sort((a, b) => a - b);
        lo[i] = Math.min(lo[i], v[Math.floor(0.02 * (v.length - 1))]);
        hi[i] = Math.max(hi[i], v[Math.ceil(0.98 * (v.length - 1))]);
      }
    }
    markers = (scene.markers || []).map((m) => ({ p: m.position, rgb: hex(m.colour), big: m.recommended }));
    // The start is the reset view: orbit about the middle of what there is to see.
    if (!(lo[0] <= hi[0])) {
      lo.fill(-100);
      hi.fill(100);
    }
    const span = Math.max(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2], 1);
    home = {
      target: [(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, (lo[2] + hi[2]) / 3],
      yaw: ((scene.view_azimuth_deg || 0) * Math.PI) / 180 - 2.2,
      pitch: 0.45,
      dist: 1.6 * span,
    };
    // Another scene keeps the view the viewer turned to; the first starts from the one kept
    // in the session, else from the reset view.
    if (view === null && persist) {
      try {
        view = JSON.parse(sessionStorage.getItem(persist));
      } catch (e) {
        view = null;
      }
    }
    if (!view || !Array.isArray(view.target)) view = JSON.parse(JSON.stringify(home));
    // What a test reads back: what was drawn, where from.
    canvas.dataset.apexes = JSON.stringify(apexes);
    canvas.dataset.posed = JSON.stringify(posed);
    canvas.dataset.clouds = JSON.stringify(counts);
  }

  // The camera's axes for the current view: right, up, back (towards the viewer).
  function axes() {
    const cp = Math.cos(view.pitch), sp = Math.sin(view.pitch);
    const back = [cp * Math.cos(view.yaw), cp * Math.sin(view.yaw), sp];
    const right = [-Math.sin(view.yaw), Math.cos(view.yaw), 0];
    const up = [
      back[1] * right[2] - back[2] * right[1],
      back[2] * right[0] - back[0] * right[2],
      back[0] * right[1] - back[1] * right[0],
    ];
    return { right: right, up: up, back: back };
  }

  function draw() {
    const w = canvas.width, h = canvas.height;
    const ax = axes();
    const eye = [0, 1, 2].map((i) => view.target[i] + view.dist * ax.back[i]);
    const focal = 0.9 * Math.min(w, h);
    const near = 1;
    // View coordinates: x right, y up, depth along the view.
    const toView = (q) => {
      const d = [q[0] - eye[0], q[1] - eye[1], q[2] - eye[2]];
      return [dot(d, ax.right), dot(d, ax.up), -dot(d, ax.back)];
    };
    const screen = (v) => [w / 2 + (focal * v[0]) / v[2], h / 2 - (focal * v[1]) / v[2]];
    ctx.fillStyle = "#f4f6f8";
    ctx.fillRect(0, 0, w, h);
    const items = [];
    for (const t of tris) {
      const a = toView(t.a), b = toView(t.b), c = toView(t.c);
      if (a[2] < near || b[2] < near || c[2] < near) continue;
      // Lit from the viewer: a face turned away from the view is drawn darker.
      const u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
      const v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
      const n = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]];
      const len = Math.hypot(n[0], n[1], n[2]) || 1;
      const shade = 0.55 + 0.45 * Math.abs(n[2] / len);
      items.push({ depth: (a[2] + b[2] + c[2]) / 3, kind: 0, pts: [screen(a), screen(b), screen(c)], t: t, shade: shade });
    }
    for (const e of edges) {
      const a = toView(e.a), b = toView(e.b);
      if (a[2] < near || b[2] < near) continue;
      items.push({ depth: Math.min(a[2], b[2]) - 1, kind: 1, pts: [screen(a), screen(b)], rgb: e.rgb });
    }
    for (const m of markers) {
      const a = toView(m.p);
      if (a[2] < near) continue;
      items.push({ depth: a[2], kind: 2, pts: [screen(a)], m: m });
    }
    for (const q of points) {
      const a = toView(q.p);
      if (a[2] < near) continue;
      items.push({ depth: a[2], kind: 3, pts: [screen(a)], rgb: q.rgb });
    }
    items.sort((x, y) => y.depth - x.depth);
    for (const it of items) {
      if (it.kind === 0) {
        const c = it.t.rgb.map((x) => Math.round(x * it.shade));
        ctx.globalAlpha = it.t.alpha;
        ctx.fillStyle = "rgb(" + c.join(",") + ")";
        ctx.beginPath();
        ctx.moveTo(it.pts[0][0], it.pts[0][1]);
        ctx.lineTo(it.pts[1][0], it.pts[1][1]);
        ctx.lineTo(it.pts[2][0], it.pts[2][1]);
        ctx.closePath();
        ctx.fill();
        // Opaque faces get a hairline of their own colour so that seams between them close.
        if (it.t.alpha >= 1) {
          ctx.strokeStyle = ctx.fillStyle;
          ctx.lineWidth = 0.6;
          ctx.stroke();
        }
      } else if (it.kind === 1) {
        ctx.globalAlpha = 1;
        ctx.strokeStyle = "rgb(" + it.rgb.join(",") + ")";
        ctx.lineWidth = 1.2;
        ctx.beginPath();
        ctx.moveTo(it.pts[0][0], it.pts[0][1]);
        ctx.lineTo(it.pts[1][0], it.pts[1][1]);
        ctx.stroke();
      } else if (it.kind === 2) {
        ctx.globalAlpha = 1;
        ctx.fillStyle = "rgb(" + it.m.rgb.join(",") + ")";
        ctx.strokeStyle = it.m.big ? "#00c800" : "#333";
        ctx.lineWidth = it.m.big ? 3 : 1;
        ctx.beginPath();
        ctx.arc(it.pts[0][0], it.pts[0][1], it.m.big ? 7 : 4.5, 0, 2 * Math.PI);
        ctx.fill();
        ctx.stroke();
      } else {
        ctx.globalAlpha = 1;
        ctx.fillStyle = "rgb(" + it.rgb.join(",") + ")";
        ctx.fillRect(it.pts[0][0] - 1.5, it.pts[0][1] - 1.5, 3, 3);
      }
    }
    ctx.globalAlpha = 1;
    canvas.dataset.drawn = String(items.length);
    if (persist) {
      try {
        sessionStorage.setItem(persist, JSON.stringify(view));
      } catch (e) {
        // A page without storage (a file page in some browsers) starts from the reset view.
      }
    }
  }

  // Mouse: orbit, pan, zoom.
  let drag = null;
  canvas.addEventListener("contextmenu", (e) => e.preventDefault());
  canvas.addEventListener("mousedown", (e) => {
    drag = { x: e.clientX, y: e.clientY, pan: e.button === 2 || e.shiftKey };
  });
  window.addEventListener("mouseup", () => {
    drag = null;
  });
  window.addEventListener("mousemove", (e) => {
    if (!drag || !view) return;
    const dx = e.clientX - drag.x, dy = e.clientY - drag.y;
    drag.x = e.clientX;
    drag.y = e.clientY;
    if (drag.pan) {
      const ax = axes();
      const k = view.dist / (0.9 * Math.min(canvas.width, canvas.height));
      for (let i = 0; i < 3; i++) view.target[i] += k * (-dx * ax.right[i] + dy * ax.up[i]);
    } else {
      view.yaw -= dx * 0.01;
      view.pitch = Math.max(-1.5, Math.min(1.5, view.pitch + dy * 0.01));
    }
    draw();
  });
  canvas.addEventListener(
    "wheel",
    (e) => {
      if (!view) return;
      e.preventDefault();
      view.dist = Math.max(10, view.dist * Math.exp(e.deltaY * 0.001));
      draw();
    },
    { passive: false }
  );
  reset.addEventListener("click", () => {
    if (!home) return;
    view = JSON.parse(JSON.stringify(home));
    draw();
  });
  window.camplaceView3d = {
    show: (scene) => {
      load(scene);
      draw();
    },
  };
  const inline = document.getElementById("scene3d");
  if (inline && inline.textContent.trim()) window.camplaceView3d.show(JSON.parse(inline.textContent));
  canvas.dataset.readyMs = String(Math.round(performance.now()));
})();
