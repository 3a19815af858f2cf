// The report's 3D view: draws the inline scene (#scene3d, world mm, z up) on a 2D canvas,
// triangles sorted far to near. Left drag orbits, right or shift drag pans, the wheel zooms.
// No WebGL: a few thousand triangles draw fast enough this way and every browser (headless
// ones without a GPU too) draws the same picture.
(function () {
  "use strict";
  const scene = JSON.parse(document.getElementById("scene3d").textContent);
  const canvas = document.getElementById("view3d-canvas");
  const ctx = canvas.getContext("2d");
  const hex = (c) => [1, 3, 5].map((i) => parseInt(c.slice(i, i + 2), 16));
  // Every drawable: triangles (with their part's colour) and marker points.
  const tris = [];
  const edges = [];
  for (const part of scene.parts) {
    const rgb = hex(part.colour);
    const p = part.positions;
    for (const t of part.triangles) {
      tris.push({ a: p[t[0]], b: p[t[1]], c: p[t[2]], rgb: rgb, alpha: part.opacity });
    }
    for (const e of part.edges || []) edges.push({ a: p[e[0]], b: p[e[1]], rgb: rgb });
  }
  const markers = scene.markers.map((m) => ({ p: m.position, rgb: hex(m.colour), big: m.recommended }));
  // The view: orbit about a target; the start is the reset view.
  const lo = [Infinity, Infinity, Infinity];
  const hi = [-Infinity, -Infinity, -Infinity];
  for (const part of scene.parts) {
    for (const q of part.positions) {
      for (let i = 0; i < 3; i++) {
        lo[i] = Math.min(lo[i], q[i]);
        hi[i] = Math.max(hi[i], q[i]);
      }
    }
  }
  const span = Math.max(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2], 1);
  const home = {
    target: [(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, (lo[2] + hi[2]) / 3],
    yaw: (scene.view_azimuth_deg * Math.PI) / 180 - 2.2,
    pitch: 0.45,
    dist: 1.6 * span,
  };
  let view = JSON.parse(JSON.stringify(home));
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
  const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
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
      } else {
        ctx.globalAlpha = 1;
        ctx.fillStyle = "rgb(" + it.m.rgb.join(",") + ")";
        ctx.strokeStyle = it.m.big ? "#00c800" : "#333";
        ctx.lineWidth = it.m.big ? 3 : 1;
        ctx.beginPath();
        ctx.arc(it.pts[0][0], it.pts[0][1], it.m.big ? 7 : 4.5, 0, 2 * Math.PI);
        ctx.fill();
        ctx.stroke();
      }
    }
    ctx.globalAlpha = 1;
    canvas.dataset.drawn = String(items.length);
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
    if (!drag) return;
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
      e.preventDefault();
      view.dist = Math.max(10, view.dist * Math.exp(e.deltaY * 0.001));
      draw();
    },
    { passive: false }
  );
  document.getElementById("view3d-reset").addEventListener("click", () => {
    view = JSON.parse(JSON.stringify(home));
    draw();
  });
  draw();
  // What a test reads back: the apex each frustum was drawn from, and when it was ready.
  const apexes = {};
  for (const part of scene.parts) if (part.kind === "frustum") apexes[part.name] = part.positions[0];
  canvas.dataset.apexes = JSON.stringify(apexes);
  canvas.dataset.readyMs = String(Math.round(performance.now()));
})();
