// The simulated Desk's page: the legacy web API (as the robot's own page uses it) for
// login and commands, /desk/api/robot/configuration (WSS, 10 Hz) for the live status.
"use strict";

const $ = (id) => document.getElementById(id);
let robot = null; // "fer" | "fr3"
let socket = null;
let controlToken = sessionStorage.getItem("controlToken");

// The legacy login's password: base64 of the comma-joined SHA-256 bytes of
// "password#user@franka", in lines of 76 characters as Python's base64.encodebytes.
async function encodePassword(user, password) {
  const data = new TextEncoder().encode(`${password}#${user}@franka`);
  const digest = new Uint8Array(await crypto.subtle.digest("SHA-256", data));
  return btoa(Array.from(digest).join(",")).replace(/.{1,76}/g, "$&\n");
}

function say(text, isError) {
  const m = $("message");
  m.textContent = text;
  m.className = isError ? "error" : "";
}

async function api(method, path, body, headers) {
  const init = { method, headers: Object.assign({}, headers || {}), credentials: "same-origin" };
  if (body !== undefined) {
    init.headers["Content-Type"] = "application/json";
    init.body = JSON.stringify(body);
  }
  const res = await fetch(path, init);
  const text = await res.text();
  if (!res.ok) {
    let detail = text;
    try { const j = JSON.parse(text); detail = j.message || j.code || text; } catch (e) { /* text */ }
    throw new Error(`${method} ${path}: ${res.status} ${detail}`);
  }
  try { return text ? JSON.parse(text) : null; } catch (e) { return text; }
}

function tokenHeader() {
  return controlToken ? { "X-Control-Token": controlToken } : {};
}

function brakePath(action) {
  if (robot === "fr3") return `/desk/api/joints/${action}`;
  return action === "unlock" ? "/desk/api/robot/open-brakes" : "/desk/api/robot/close-brakes";
}

async function act(label, fn) {
  try {
    await fn();
    say(`${label}: done`, false);
  } catch (e) {
    say(`${label}: ${e.message}`, true);
  }
  refresh();
}

function setToken(token) {
  controlToken = token;
  if (token) sessionStorage.setItem("controlToken", token);
  else sessionStorage.removeItem("controlToken");
}

async function take(force) {
  const res = await api("POST", "/admin/api/control-token/request" + (force ? "?force" : ""),
    { requestedBy: sessionStorage.getItem("user") });
  setToken(res.token);
  if (force) {
    const button = robot === "fr3" ? "top" : "circle";
    say(`confirm by pressing the Pilot's ${button} button`, false);
  }
}

const ROBOT_MODES = ["Other", "Idle", "Move", "Guiding", "Reflex", "User stopped", "Automatic error recovery"];

function show(status) {
  const set = (id, text) => { const e = $(id); e.textContent = text; e.className = text; };
  set("status-brakes", status.brakes);
  set("status-fci", status.fci ? "Active" : "Inactive");
  set("status-mode", status.operatingMode);
  $("status-robot-mode").textContent =
    status.robotMode === null || status.robotMode === undefined ? "?" : ROBOT_MODES[status.robotMode] || String(status.robotMode);
  const owner = status.controlToken ? status.controlToken.ownedBy : "nobody";
  $("status-owner").textContent = owner;
  $("status-errors").textContent = status.recovery ? status.recovery.type : "none";
  if (status.jointAngles) showArm(status.jointAngles, status.cartesianPose, status.time);
}

function showArm(q, pose, t) {
  const list = $("joints");
  while (list.children.length < 7) list.appendChild(document.createElement("li"));
  q.forEach((v, i) => { list.children[i].textContent = (v * 180 / Math.PI).toFixed(2); });
  // O_T_EE is column-major: the translation is elements 12..14.
  $("ee-position").textContent =
    `x ${pose[12].toFixed(4)} m, y ${pose[13].toFixed(4)} m, z ${pose[14].toFixed(4)} m`;
  const rows = [0, 1, 2, 3].map((r) => [0, 1, 2, 3].map((c) => pose[c * 4 + r].toFixed(3).padStart(7)).join(" "));
  $("ee-pose").textContent = rows.join("\n");
  $("arm-time").textContent = t !== undefined ? `t = ${t.toFixed(1)} s` : "";
  draw(q);
}

// Forward kinematics (modified DH of the FER/FR3 arm, Franka's published table) for the
// drawing only: joint origins in the base frame.
const DH = [[0, 0, 0.333], [-Math.PI / 2, 0, 0], [Math.PI / 2, 0, 0.316], [Math.PI / 2, 0.0825, 0],
  [-Math.PI / 2, -0.0825, 0.384], [Math.PI / 2, 0, 0], [Math.PI / 2, 0.088, 0]];

function matmul(a, b) {
  const out = new Array(16).fill(0);
  for (let r = 0; r < 4; r++) for (let c = 0; c < 4; c++) for (let k = 0; k < 4; k++) out[r * 4 + c] += a[r * 4 + k] * b[k * 4 + c];
  return out;
}

function dh(alpha, a, d, theta) {
  const ca = Math.cos(alpha), sa = Math.sin(alpha), ct = Math.cos(theta), st = Math.sin(theta);
  return [ct, -st, 0, a, st * ca, ct * ca, -sa, -d * sa, st * sa, ct * sa, ca, d * ca, 0, 0, 0, 1];
}

function jointPoints(q) {
  let T = [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1];
  const pts = [[0, 0, 0]];
  for (let i = 0; i < 7; i++) {
    T = matmul(T, dh(DH[i][0], DH[i][1], DH[i][2], q[i]));
    pts.push([T[3], T[7], T[11]]);
  }
  T = matmul(T, dh(0, 0, 0.107, 0)); // flange
  pts.push([T[3], T[7], T[11]]);
  return pts;
}

function draw(q) {
  const c = $("view"), g = c.getContext("2d");
  g.clearRect(0, 0, c.width, c.height);
  const pts = jointPoints(q), s = 220;
  const views = [{ ox: 130, oy: 270, label: "side (x, z)", p: (v) => [v[0], v[2]] },
    { ox: 390, oy: 150, label: "top (x, y)", p: (v) => [v[0], v[1]] }];
  for (const view of views) {
    g.fillStyle = "#6b7280"; g.fillText(view.label, view.ox - 100, 15);
    g.strokeStyle = "#374151"; g.lineWidth = 6; g.lineCap = "round"; g.beginPath();
    pts.forEach((v, i) => {
      const [x, y] = view.p(v), px = view.ox + s * x, py = view.oy - s * y;
      if (i === 0) g.moveTo(px, py); else g.lineTo(px, py);
    });
    g.stroke();
    g.fillStyle = "#f59e0b";
    for (const v of pts) { const [x, y] = view.p(v); g.beginPath(); g.arc(view.ox + s * x, view.oy - s * y, 4, 0, 7); g.fill(); }
  }
}

async function refresh() {
  try {
    const s = await api("GET", "/admin/api/system-status");
    robot = s.robot;
    $("robot-name").textContent = robot === "fr3" ? "FR3 (simulated)" : "FER / Panda (simulated)";
    $("pilot-top").hidden = robot !== "fr3";
    $("confirm-hint").textContent =
      `A forced take of control is confirmed with the ${s.pilotConfirmButton} button.`;
    show({
      brakes: s.safety.brakeState[0], fci: s.fci.active, operatingMode: s.derived.operatingMode,
      controlToken: s.controlToken.activeToken, recovery: s.safety.recovery,
      jointAngles: s.arm ? s.arm.q : null, cartesianPose: s.arm ? s.arm.O_T_EE : null,
      robotMode: s.arm ? s.arm.robot_mode : null, time: s.arm ? s.arm.time : undefined,
    });
    return true;
  } catch (e) {
    if (String(e.message).includes(" 401")) loggedOut();
    return false;
  }
}

function connectLive() {
  if (socket) socket.close();
  socket = new WebSocket(`wss://${location.host}/desk/api/robot/configuration`);
  socket.onmessage = (ev) => show(JSON.parse(ev.data));
  socket.onclose = () => { socket = null; if (!$("desk-panel").hidden) setTimeout(connectLive, 1000); };
}

function loggedIn(user) {
  $("login-panel").hidden = true;
  $("desk-panel").hidden = false;
  $("logout").hidden = false;
  $("who").textContent = user;
  connectLive();
}

function loggedOut() {
  $("login-panel").hidden = false;
  $("desk-panel").hidden = true;
  $("logout").hidden = true;
  $("who").textContent = "";
  if (socket) { const s = socket; socket = null; s.onclose = null; s.close(); }
}

$("login-form").addEventListener("submit", async (ev) => {
  ev.preventDefault();
  const user = $("login-user").value, password = $("login-password").value;
  try {
    const session = await api("POST", "/admin/api/login",
      { login: user, password: await encodePassword(user, password) });
    document.cookie = `authorization=${session}; path=/; secure; samesite=strict`;
    sessionStorage.setItem("user", user);
    $("login-password").value = "";
    await refresh();
    loggedIn(user);
    say("", false);
  } catch (e) {
    say(e.message.includes(" 401") ? "wrong user name or password" : e.message, true);
    $("login-panel").appendChild($("message"));
  }
});

$("logout").onclick = () => act("log out", async () => {
  await api("POST", "/admin/api/logout");
  document.cookie = "authorization=; path=/; max-age=0";
  loggedOut();
});
$("take").onclick = () => act("take control", () => take(false));
$("take-force").onclick = () => act("take control (force)", () => take(true));
$("release").onclick = () => act("release control", async () => {
  await api("DELETE", "/admin/api/control-token", { token: controlToken || "" });
  setToken(null);
});
$("unlock").onclick = () => act("unlock", () => api("POST", brakePath("unlock"), undefined, tokenHeader()));
$("lock").onclick = () => act("lock", () => api("POST", brakePath("lock"), undefined, tokenHeader()));
$("fci-on").onclick = () => act("activate FCI", () => api("POST", "/admin/api/control-token/fci", { token: controlToken || "" }));
$("fci-off").onclick = () => act("deactivate FCI", () => api("DELETE", "/admin/api/control-token/fci", { token: controlToken || "" }));
$("recover").onclick = () => act("recover", async () => {
  const s = await api("GET", "/admin/api/system-status");
  const id = s.safety.recovery ? s.safety.recovery.type : "TD2Timeout";
  await api("POST", `/admin/api/safety/recoverable-safety-errors/acknowledge?error_id=${encodeURIComponent(id)}`, undefined, tokenHeader());
});
for (const b of document.querySelectorAll(".pilot button")) {
  b.onclick = () => act(`Pilot ${b.dataset.button}`, () => api("POST", `/desk/api/sim/pilot/${b.dataset.button}`));
}

refresh().then((ok) => { if (ok) loggedIn(sessionStorage.getItem("user") || ""); });
