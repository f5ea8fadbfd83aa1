// sage3d view: the page of `sage3d view`. Plain JavaScript, no library: it asks the local
// server for the map, frames and sessions (see the server's route table) and draws them.
"use strict";

const $ = (id) => document.getElementById(id);
const token = new URLSearchParams(location.search).get("token");

// Everything the page knows, readable from the console (and by the browser tests).
const viewer = {
  info: null, // GET /api/info
  scene: null, // the scene shown
  map: null, // its map's frame and objects
  mapImage: null, // its map image
  mode: "explore", // explore | player | play
  state: null, // the session's state (explore, play)
  session: null, // its id
  episode: null, // the player's episode (GET /api/episodes/{id})
  index: 0, // the player's step (0: the start)
  layer: "rgb",
  mapVisible: true,
  stopArmed: false, // S pressed once in play: press again to STOP
  frames: 0, // frames shown so far
  busy: false,
};
window.viewer = viewer;

function withToken(path) {
  if (!token) return path;
  return path + (path.includes("?") ? "&" : "?") + "token=" + encodeURIComponent(token);
}

async function api(path, body) {
  const opts = body === undefined ? {} : {
    method: "POST",
    headers: { "content-type": "application/json" },
    body: JSON.stringify(body),
  };
  const r = await fetch(withToken(path), opts);
  const data = await r.json().catch(() => ({ error: r.statusText }));
  if (!r.ok) throw new Error(data.error || r.statusText);
  return data;
}

function say(text, bad) {
  const m = $("message");
  m.textContent = text || "";
  m.className = bad ? "bad" : "";
}

const fmt = (v, d = 2) => (v === null || v === undefined ? "–" : Number(v).toFixed(d));

// ---------- the map ----------

async function showScene(scene) {
  if (viewer.scene === scene && viewer.map) return;
  viewer.scene = scene;
  $("scene").value = scene;
  viewer.map = await api(`/api/scenes/${encodeURIComponent(scene)}/map`);
  const img = new Image();
  await new Promise((ok, fail) => {
    img.onload = ok;
    img.onerror = () => fail(new Error("map image"));
    img.src = withToken(`/api/scenes/${encodeURIComponent(scene)}/map.png`);
  });
  viewer.mapImage = img;
  fitMap();
}

// The map canvas as wide as its panel (at most twice the image), its height in proportion.
function fitMap() {
  const img = viewer.mapImage;
  if (!img) return;
  const c = $("map");
  const w = Math.max(200, Math.min($("map-wrap").clientWidth, 2 * img.width));
  c.width = w;
  c.height = Math.round((img.height * w) / img.width);
}

// World metres to canvas pixels.
function toCanvas(x, y) {
  const m = viewer.map;
  const k = $("map").width / m.width;
  return [((x - m.origin[0]) / m.scale) * k, (m.height - (y - m.origin[1]) / m.scale) * k];
}

function toWorld(px, py) {
  const m = viewer.map;
  const k = $("map").width / m.width;
  return [m.origin[0] + (px / k) * m.scale, m.origin[1] + (m.height - py / k) * m.scale];
}

function line(ctx, pts, colour, width, dash) {
  if (pts.length < 2) return;
  ctx.save();
  ctx.strokeStyle = colour;
  ctx.lineWidth = width;
  ctx.setLineDash(dash || []);
  ctx.beginPath();
  pts.forEach(([x, y], i) => {
    const [u, v] = toCanvas(x, y);
    i ? ctx.lineTo(u, v) : ctx.moveTo(u, v);
  });
  ctx.stroke();
  ctx.restore();
}

function marker(ctx, x, y, shape, colour, r) {
  const [u, v] = toCanvas(x, y);
  ctx.save();
  ctx.fillStyle = colour;
  ctx.strokeStyle = colour;
  ctx.lineWidth = 3;
  ctx.beginPath();
  if (shape === "square") ctx.rect(u - r, v - r, 2 * r, 2 * r);
  else if (shape === "diamond") {
    ctx.moveTo(u, v - r); ctx.lineTo(u + r, v); ctx.lineTo(u, v + r); ctx.lineTo(u - r, v);
    ctx.closePath();
  }
  if (shape === "cross") {
    ctx.moveTo(u - r, v - r); ctx.lineTo(u + r, v + r);
    ctx.moveTo(u + r, v - r); ctx.lineTo(u - r, v + r);
    ctx.stroke();
  } else ctx.fill();
  ctx.restore();
}

// The agent: a field-of-view wedge of the preset's width and an arrow along its heading.
function agent(ctx, x, y, yaw) {
  const [u, v] = toCanvas(x, y);
  const half = ((viewer.info.preset.hfov_deg || 90) * Math.PI) / 360;
  const reach = 40;
  ctx.save();
  ctx.fillStyle = "rgba(0, 114, 178, 0.25)";
  ctx.beginPath();
  ctx.moveTo(u, v);
  ctx.arc(u, v, reach, -yaw - half, -yaw + half);
  ctx.closePath();
  ctx.fill();
  ctx.fillStyle = "#0072b2";
  ctx.strokeStyle = "white";
  ctx.lineWidth = 1.5;
  ctx.beginPath();
  const tip = (a, r) => [u + r * Math.cos(-yaw + a), v + r * Math.sin(-yaw + a)];
  ctx.moveTo(...tip(0, 11));
  ctx.lineTo(...tip(2.5, 8));
  ctx.lineTo(...tip(-2.5, 8));
  ctx.closePath();
  ctx.fill();
  ctx.stroke();
  ctx.restore();
}

function drawMap() {
  const c = $("map");
  const ctx = c.getContext("2d");
  ctx.clearRect(0, 0, c.width, c.height);
  if (!viewer.mapVisible) {
    ctx.fillStyle = "#eee";
    ctx.fillRect(0, 0, c.width, c.height);
    ctx.fillStyle = "#555";
    ctx.font = "16px sans-serif";
    ctx.fillText("map hidden: an agent does not see it", 20, 30);
    return;
  }
  if (!viewer.mapImage) return;
  ctx.imageSmoothingEnabled = false;
  ctx.drawImage(viewer.mapImage, 0, 0, c.width, c.height);
  roomLabels(ctx);
  const e = viewer.episode;
  if (viewer.mode === "player" && e && e.start) {
    if (e.goal && e.goal.footprint) line(ctx, [...e.goal.footprint, e.goal.footprint[0]], "#e69f00", 2);
    line(ctx, e.reference_path, "#009e73", 3, [8, 6]);
    const upto = e.steps.slice(0, viewer.index);
    line(ctx, [[e.start.x, e.start.y], ...upto.map((s) => [s.x, s.y])], "#0072b2", 3);
    marker(ctx, e.start.x, e.start.y, "square", "#56b4e9", 6);
    if (e.goal) marker(ctx, e.goal.point[0], e.goal.point[1], "diamond", "#e69f00", 8);
    upto.filter((s) => s.contact).forEach((s) => marker(ctx, s.x, s.y, "cross", "#d55e00", 5));
    const p = poseAt(viewer.index);
    agent(ctx, p.x, p.y, p.yaw);
  } else if (viewer.state) {
    const s = viewer.state;
    // A played episode's reference path and goal would tell the way: only the map shows them.
    if (viewer.mode === "explore") {
      line(ctx, s.reference_path, "#009e73", 3, [8, 6]);
      if (s.goal) marker(ctx, s.goal[0], s.goal[1], "diamond", "#e69f00", 8);
    }
    line(ctx, s.path, "#0072b2", 3);
    if (s.path.length) marker(ctx, s.path[0][0], s.path[0][1], "square", "#56b4e9", 6);
    (viewer.contacts || []).forEach(([x, y]) => marker(ctx, x, y, "cross", "#d55e00", 5));
    agent(ctx, s.pose.x, s.pose.y, s.pose.yaw);
  }
}

// Each room's type at the middle of its outline.
function roomLabels(ctx) {
  ctx.save();
  ctx.font = "11px sans-serif";
  ctx.textAlign = "center";
  ctx.fillStyle = "rgba(40, 40, 40, 0.75)";
  for (const r of viewer.map.rooms) {
    if (!r.polygon.length) continue;
    const x = r.polygon.reduce((a, p) => a + p[0], 0) / r.polygon.length;
    const y = r.polygon.reduce((a, p) => a + p[1], 0) / r.polygon.length;
    const [u, v] = toCanvas(x, y);
    ctx.fillText(r.type.replace(/_/g, " "), u, v);
  }
  ctx.restore();
}

function inside(poly, x, y) {
  let hit = false;
  for (let i = 0, j = poly.length - 1; i < poly.length; j = i++) {
    const [xi, yi] = poly[i];
    const [xj, yj] = poly[j];
    if (yi > y !== yj > y && x < ((xj - xi) * (y - yi)) / (yj - yi) + xi) hit = !hit;
  }
  return hit;
}

// What lies under world point (x, y): the object, else the door, else the room.
function under(x, y) {
  const m = viewer.map;
  const item = m.items.find((i) => !i.state && inside(i.polygon, x, y));
  if (item) return `${item.id} (${item.category})`;
  const door = m.doors.find((d) => inside(d.polygon, x, y));
  if (door) return `door (${door.state})`;
  const room = m.rooms.find((r) => inside(r.polygon, x, y));
  return room ? `${room.type} (${fmt(room.area_m2, 1)} m²)` : null;
}

function onMapMove(ev) {
  const tip = $("tip");
  if (!viewer.map || !viewer.mapVisible) return (tip.hidden = true);
  const r = $("map").getBoundingClientRect();
  const [x, y] = toWorld(ev.clientX - r.left, ev.clientY - r.top);
  const what = under(x, y);
  tip.hidden = !what;
  if (what) {
    tip.textContent = `${what}  (${fmt(x)}, ${fmt(y)})`;
    tip.style.left = `${ev.clientX - r.left + 12}px`;
    tip.style.top = `${ev.clientY - r.top + 12}px`;
  }
}

async function onMapClick(ev) {
  if (viewer.mode !== "explore" || !viewer.session || !viewer.map) return;
  const r = $("map").getBoundingClientRect();
  const [x, y] = toWorld(ev.clientX - r.left, ev.clientY - r.top);
  try {
    viewer.state = await api(`/api/sessions/${viewer.session}/place`, { x, y, yaw: viewer.state.pose.yaw });
    viewer.contacts = [];
    say(`placed at (${fmt(x)}, ${fmt(y)})`);
    refresh();
  } catch (e) {
    say(e.message, true);
  }
}

// ---------- the first-person view ----------

let pendingFrame = null;
let loadingFrame = false;

function frameSize() {
  const play = viewer.info.play;
  if (viewer.mode === "play" && play && play.size) return play.size;
  return [640, 480];
}

// Asks for the frame at `pose`; while one loads, only the newest request waits.
function showFrame(pose, pitch) {
  const [w, h] = frameSize();
  const q = new URLSearchParams({
    x: pose.x, y: pose.y, z: pose.z, yaw: pose.yaw, pitch: pitch || 0,
    width: w, height: h, layer: viewer.layer, format: "jpeg",
  });
  pendingFrame = withToken(`/api/scenes/${encodeURIComponent(viewer.scene)}/frame?${q}`);
  if (!loadingFrame) nextFrame();
}

function nextFrame() {
  if (!pendingFrame) return;
  const url = pendingFrame;
  pendingFrame = null;
  loadingFrame = true;
  const img = $("fpv");
  img.onload = img.onerror = () => {
    loadingFrame = false;
    viewer.frames += 1;
    img.dataset.src = url;
    nextFrame();
  };
  img.src = url;
}

// ---------- explore and play sessions ----------

async function openSession(body) {
  viewer.state = await api("/api/sessions", body);
  viewer.session = viewer.state.session;
  viewer.contacts = [];
  viewer.stopArmed = false;
  await showScene(viewer.state.scene);
  refresh();
}

async function act(action) {
  if (viewer.mode === "player") return;
  if (!viewer.session || viewer.busy) return;
  if (viewer.state.done) return say("the episode has ended: pick another, or click the map to place the agent", true);
  if (action === "stop" && viewer.mode === "play" && !viewer.stopArmed) {
    viewer.stopArmed = true;
    return say("press S (or STOP) again to end the episode here");
  }
  viewer.stopArmed = false;
  viewer.busy = true;
  try {
    const s = await api(`/api/sessions/${viewer.session}/step`, { action });
    viewer.state = s;
    if (s.contact) viewer.contacts.push([s.pose.x, s.pose.y]);
    if (s.record) finished(s);
    else say("");
    refresh();
  } catch (e) {
    say(e.message, true);
  } finally {
    viewer.busy = false;
  }
}

// A played episode ended: its record, scored as any agent's.
async function finished(s) {
  const r = s.record;
  say(`episode ${r.id} recorded: ${r.termination}, SR ${fmt(r.sr, 0)}, NE ${fmt(r.ne)} m, CR ${fmt(r.cr, 0)}, SPL ${fmt(r.spl)}`);
  viewer.info = await api("/api/info");
  listEpisodes();
}

function refresh() {
  drawMap();
  const s = viewer.state;
  if (viewer.mode === "player") return showPlayerStep();
  if (!s) return;
  showFrame(s.pose, s.pitch);
  const parts = [
    `step ${s.step}`,
    `pose (${fmt(s.pose.x)}, ${fmt(s.pose.y)}) yaw ${fmt((s.pose.yaw * 180) / Math.PI, 0)}°`,
  ];
  if (s.action) parts.push(`action ${s.action}`);
  if (s.episode && s.distance_to_goal !== null && viewer.mode !== "play") parts.push(`distance to goal ${fmt(s.distance_to_goal)} m`);
  if (s.done) parts.push(`ended: ${s.termination}`);
  $("status").textContent = parts.join(" · ");
  $("status").dataset.step = s.step;
  showContact(s.contact, s.intensity);
}

function showContact(contact, intensity) {
  const c = $("contact");
  c.hidden = !contact;
  c.textContent = contact ? `contact  c(t) = ${fmt(intensity)}` : "";
  $("fpv-box").classList.toggle("hit", !!contact);
}

// ---------- the episode player (a run) ----------

function poseAt(i) {
  const e = viewer.episode;
  return i === 0 ? e.start : e.steps[i - 1];
}

async function openEpisode(id) {
  viewer.mode = "player";
  viewer.episode = await api(`/api/episodes/${encodeURIComponent(id)}`);
  const e = viewer.episode;
  await showScene(e.scene);
  $("timeline").max = e.steps.length;
  setIndex(0);
  showInstruction(e.instruction);
  say(e.error ? `faulted: ${e.error}` : "");
  setMode("player");
}

function setIndex(i) {
  const e = viewer.episode;
  if (!e || !e.start) return;
  viewer.index = Math.max(0, Math.min(e.steps.length, i));
  $("timeline").value = viewer.index;
  refresh();
}

function showPlayerStep() {
  const e = viewer.episode;
  if (!e || !e.start) return;
  const i = viewer.index;
  const p = poseAt(i);
  showFrame(p, 0);
  const s = i > 0 ? e.steps[i - 1] : null;
  $("step-label").textContent = `step ${i}/${e.steps.length}`;
  const parts = [`step ${i}/${e.steps.length}`, `pose (${fmt(p.x)}, ${fmt(p.y)})`];
  if (s) {
    parts.push(`action ${s.action}`);
    if (s.geodesic_to_goal !== null) parts.push(`distance to goal ${fmt(s.geodesic_to_goal)} m`);
  }
  parts.push(`outcome ${e.termination || "faulted"} · SR ${fmt(e.sr, 0)} · NE ${fmt(e.ne)} · CR ${fmt(e.cr, 0)}`);
  $("status").textContent = parts.join(" · ");
  $("status").dataset.step = i;
  showContact(s && s.contact, s ? s.intensity : 0);
}

let playing = null;
function togglePlay() {
  if (playing) {
    clearInterval(playing);
    playing = null;
    $("play-btn").textContent = "play";
    return;
  }
  $("play-btn").textContent = "pause";
  playing = setInterval(() => {
    if (viewer.index >= viewer.episode.steps.length) return togglePlay();
    setIndex(viewer.index + 1);
  }, 250);
}

// ---------- the episode list ----------

function showInstruction(text) {
  const box = $("instruction");
  box.hidden = !text;
  box.textContent = text || "";
}

function setMode(mode) {
  viewer.mode = mode;
  const words = { explore: "explore", player: "episode player", play: "human play" };
  $("mode").textContent = words[mode];
  $("controls").classList.toggle("off", mode === "player");
  $("player").hidden = !(mode === "player" && viewer.episode && viewer.episode.start);
  $("show-map").hidden = !(mode === "play" && !viewer.mapVisible);
  drawMap();
}

function listEpisodes() {
  const ul = $("episodes");
  const words = $("search").value.toLowerCase().split(/\s+/).filter(Boolean);
  ul.textContent = "";
  const eps = viewer.info.episodes.filter((e) => {
    const text = `${e.id} ${e.scene} ${e.instruction || ""}`.toLowerCase();
    return words.every((w) => text.includes(w));
  });
  for (const e of eps) {
    const li = document.createElement("li");
    li.dataset.id = e.id;
    const head = document.createElement("div");
    head.className = "head";
    const ok = e.sr === 1 ? "ok" : e.sr === 0 ? "miss" : "";
    const outcome = e.termination || e.error
      ? `${e.error ? "faulted" : e.termination} · SR ${fmt(e.sr, 0)} · NE ${fmt(e.ne)} · CR ${fmt(e.cr, 0)}`
      : (viewer.info.kind === "play" ? "not played" : e.task);
    head.innerHTML = `<b></b> <span class="outcome ${ok}"></span>`;
    head.querySelector("b").textContent = e.id;
    head.querySelector(".outcome").textContent = outcome;
    const text = document.createElement("div");
    text.className = "text";
    text.textContent = e.instruction || "";
    li.append(head, text);
    li.onclick = () => pick(e).catch((err) => say(err.message, true));
    ul.append(li);
  }
  const play = viewer.info.play;
  $("progress").textContent = play ? `${play.played} of ${play.total} played → ${play.folder}` : "";
}

async function pick(e) {
  document.querySelectorAll("#episodes li").forEach((li) => li.classList.toggle("sel", li.dataset.id === e.id));
  const kind = viewer.info.kind;
  if (kind === "run") return openEpisode(e.id);
  if (kind === "play") {
    if (e.played) return openEpisode(e.id);
    viewer.mapVisible = false;
    setMode("play");
    showInstruction(e.instruction);
    await openSession({ episode: e.id, play: true });
    return say("playing: move with W/A/D (or the arrows), press S twice to STOP where you think the goal is");
  }
  viewer.mapVisible = true;
  setMode("explore");
  showInstruction(e.instruction);
  await openSession({ episode: e.id });
}

// ---------- keys and controls ----------

function onKey(ev) {
  if (ev.target.tagName === "INPUT" && ev.target.type !== "radio" && ev.target.type !== "range") return;
  const k = ev.key;
  if (viewer.mode === "player") {
    if (k === " ") togglePlay();
    else if (k === "]" || k === "ArrowRight") setIndex(viewer.index + 1);
    else if (k === "[" || k === "ArrowLeft") setIndex(viewer.index - 1);
    else return;
    return ev.preventDefault();
  }
  const action = {
    w: "forward", W: "forward", ArrowUp: "forward",
    a: "left", A: "left", ArrowLeft: "left",
    d: "right", D: "right", ArrowRight: "right",
    s: "stop", S: "stop", ArrowDown: "stop",
    q: "look_up", Q: "look_up", e: "look_down", E: "look_down",
  }[k];
  if (!action) return;
  ev.preventDefault();
  if ((action === "look_up" || action === "look_down") && !viewer.info.preset.look_deg) return;
  act(action);
}

async function start() {
  viewer.info = await api("/api/info");
  $("title").textContent = viewer.info.title;
  const sel = $("scene");
  for (const s of viewer.info.scenes) sel.append(new Option(s, s));
  sel.onchange = async () => {
    viewer.mapVisible = true;
    viewer.episode = null;
    setMode("explore");
    showInstruction("");
    await openSession({ scene: sel.value });
  };
  $("scene-pick").hidden = viewer.info.kind === "play";
  $("search").oninput = listEpisodes;
  $("search").hidden = !viewer.info.episodes.length;
  $("episodes").hidden = !viewer.info.episodes.length;
  listEpisodes();
  $("map").addEventListener("mousemove", onMapMove);
  $("map").addEventListener("mouseleave", () => ($("tip").hidden = true));
  $("map").addEventListener("click", onMapClick);
  document.addEventListener("keydown", onKey);
  window.addEventListener("resize", () => {
    fitMap();
    drawMap();
  });
  document.querySelectorAll("#controls button").forEach((b) => (b.onclick = () => act(b.dataset.action)));
  document.querySelectorAll("input[name=layer]").forEach((r) => (r.onchange = () => {
    viewer.layer = r.value;
    refresh();
  }));
  $("timeline").oninput = () => setIndex(Number($("timeline").value));
  $("play-btn").onclick = togglePlay;
  $("video-btn").onclick = () => {
    if (viewer.episode) location.href = withToken(`/api/episodes/${encodeURIComponent(viewer.episode.id)}/video.gif`);
  };
  $("show-map").onclick = async () => {
    viewer.mapVisible = true;
    if (viewer.session) await api(`/api/sessions/${viewer.session}/map`, {});
    setMode(viewer.mode);
    say("the map is shown: this episode's record notes it");
  };
  if (viewer.info.kind === "play") {
    setMode("play");
    viewer.mapVisible = false;
    drawMap();
    say("pick an episode to play; you see what an agent sees (the map only if you ask, which the record notes)");
  } else if (viewer.info.kind === "run" && viewer.info.episodes.length) {
    await pick(viewer.info.episodes[0]);
  } else if (viewer.info.kind === "dataset" && viewer.info.episodes.length) {
    await pick(viewer.info.episodes[0]);
  } else {
    setMode("explore");
    await openSession({ scene: viewer.info.scenes[0] });
  }
  document.body.dataset.ready = "1";
}

start().catch((e) => say(e.message, true));
