// The signlane monitor page: one WebSocket to /monitor; each frame arrives as its state (text
// JSON) then its JPEG (binary); the page acks once it has drawn it, and only then does the
// server send the next one (newest first), so a slow page never builds a queue.
"use strict";
const view = document.getElementById("view");
const ctx = view.getContext("2d");
const $ = (id) => document.getElementById(id);
const WINDOW_S = 30;  // seconds shown in the plots
const series = [];    // [index, t, steering, throttle, speed, latency, perceive]
let topic = "rgb", pending = null, ws = null, drawn = 0;
window.monitor = {frames: () => drawn, topic: () => topic, setTopic: (t) => choose(t)};

function choose(t) {
  topic = t;
  for (const b of document.querySelectorAll("#topics button")) b.classList.toggle("on", b.dataset.topic === t);
  if (ws && ws.readyState === 1) ws.send(JSON.stringify({topic: t}));
}

fetch("/api/topics").then((r) => r.json()).then((topics) => {
  for (const [name, about] of Object.entries(topics)) {
    const b = document.createElement("button");
    b.textContent = name; b.title = about; b.dataset.topic = name;
    b.onclick = () => choose(name);
    $("topics").appendChild(b);
  }
  choose(topic);
});

function connect() {
  ws = new WebSocket(`ws://${location.host}/monitor`);
  ws.binaryType = "blob";
  ws.onopen = () => { $("conn").textContent = "live"; $("conn").className = "muted"; ws.send(JSON.stringify({topic})); };
  ws.onclose = () => { $("conn").textContent = "disconnected, retrying…"; $("conn").className = "bad"; setTimeout(connect, 1000); };
  ws.onmessage = (ev) => {
    if (typeof ev.data === "string") {
      const msg = JSON.parse(ev.data);
      if (msg.type === "state") { pending = msg; showState(msg); }
      else if (msg.type === "error") console.warn("monitor:", msg.error);
      return;
    }
    const state = pending; pending = null;
    createImageBitmap(ev.data).then((bmp) => {
      draw(bmp, state);
      drawn += 1;
      ws.send(JSON.stringify({ack: state ? state.seq : 0}));
    }, () => ws.send(JSON.stringify({ack: 0})));
  };
}

function draw(bmp, s) {
  ctx.drawImage(bmp, 0, 0, view.width, view.height);
  if (!s || !s.aligned || !$("overlay").checked) return;
  const kx = view.width / s.width, ky = view.height / s.height;
  const line = (pts, colour) => {
    if (!pts || pts.length < 2) return;
    ctx.strokeStyle = colour; ctx.lineWidth = 2; ctx.beginPath();
    pts.forEach(([x, y], i) => (i ? ctx.lineTo(x * kx, y * ky) : ctx.moveTo(x * kx, y * ky)));
    ctx.stroke();
  };
  line(s.lane.left, "#0078ff"); line(s.lane.right, "#00c800");
  ctx.font = "12px sans-serif";
  for (const sign of s.signs) {
    const [x, y, w, h] = sign.box;
    ctx.strokeStyle = sign.label === "stop" ? "#ff3030" : "#ff40d0";
    ctx.strokeRect(x * kx, y * ky, w * kx, h * ky);
    ctx.fillStyle = ctx.strokeStyle;
    ctx.fillText(`${sign.label} ${sign.score.toFixed(2)}`, x * kx, Math.max(10, y * ky - 3));
  }
  ctx.fillStyle = "rgba(0,0,0,0.55)"; ctx.fillRect(4, 4, 250, 22);
  ctx.fillStyle = "#fff"; ctx.font = "14px sans-serif";
  ctx.fillText(`${s.command.state}  steer ${s.command.steering.toFixed(2)}  thr ${s.command.throttle.toFixed(2)}`, 10, 20);
}

function showState(s) {
  $("fps").textContent = s.fps.toFixed(1);
  for (const row of s.samples) series.push(row);
  if (s.seq === 0) return;
  $("source").textContent = s.source || "";
  $("state").textContent = s.command.state;
  $("steering").textContent = s.command.steering.toFixed(3);
  $("throttle").textContent = s.command.throttle.toFixed(3);
  $("speed").textContent = `${s.speed.toFixed(2)} m/s`;
  $("latency").textContent = s.latency_ms == null ? "-" : `${s.latency_ms.toFixed(1)} ms`;
  $("lane").textContent = s.lane.found ? `${s.lane.method} (${s.lane.basis}) offset ${s.lane.offset.toFixed(2)}` : `${s.lane.method}: not found`;
  $("confirmed").textContent = s.confirmed.length ? s.confirmed.join(", ") : "none";
  $("signs").textContent = s.signs.length ? s.signs.map((x) => x.label).join(", ") : "none";
  $("timing").textContent = Object.entries(s.timing_ms).filter(([k]) => !k.includes("_")).map(([k, v]) => `${k} ${v.toFixed(1)}`).join(", ");
  $("frame").textContent = `#${s.seq} t ${s.t.toFixed(2)} s ${s.width}x${s.height} (${s.topic})`;
  const t1 = series.length ? series[series.length - 1][1] : 0;
  while (series.length && series[0][1] < t1 - WINDOW_S) series.shift();
  plot("plot-steering", [[2, "#ffd24a"]], -1, 1);
  plot("plot-speed", [[4, "#6ad0ff"]], 0, null);
  plot("plot-latency", [[5, "#ff8a6a"], [6, "#9be37a"]], 0, null);
}

function plot(id, lines, lo, hi) {
  const c = $(id), g = c.getContext("2d");
  g.clearRect(0, 0, c.width, c.height);
  if (series.length < 2) return;
  const t0 = series[series.length - 1][1] - WINDOW_S;
  let top = hi;
  if (top == null) { top = 1e-6; for (const r of series) for (const [k] of lines) if (r[k] != null) top = Math.max(top, r[k] * 1.1); }
  const X = (t) => ((t - t0) / WINDOW_S) * c.width, Y = (v) => c.height - ((v - lo) / (top - lo)) * c.height;
  g.strokeStyle = "#333"; g.beginPath(); g.moveTo(0, Y(0)); g.lineTo(c.width, Y(0)); g.stroke();
  for (const [k, colour] of lines) {
    g.strokeStyle = colour; g.beginPath();
    let started = false;
    for (const r of series) { if (r[k] == null) continue; started ? g.lineTo(X(r[1]), Y(r[k])) : g.moveTo(X(r[1]), Y(r[k])); started = true; }
    g.stroke();
  }
  g.fillStyle = "#9aa3ad"; g.font = "10px sans-serif"; g.fillText(top.toFixed(top < 10 ? 2 : 0), 2, 10);
}
connect();
