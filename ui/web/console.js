// mrroc operator console: polls the JSON API of `mrroc-ui serve` and sends operator commands.
// Plain JavaScript, no libraries. API: docs/operating.md.
"use strict";

const PLOT_WINDOW_S = 20;
const SEVERITIES = ["DEBUG", "INFO", "WARNING", "ERROR", "FATAL"];
const COLOURS = ["#0969da", "#cf222e", "#1a7f37", "#9a6700", "#8250df", "#bc4c00", "#1b7c83"];

// The API token (of [ui] token_file, or the one `mrroc-ui serve` generated and wrote to the file
// it names) comes once in the address (?token=...), is kept for the tab and sent in the header
// only (the API refuses it in a query string).
const params = new URLSearchParams(window.location.search);
if (params.get("token")) {
  sessionStorage.setItem("mrroc-token", params.get("token"));
  history.replaceState(null, "", window.location.pathname);
}
const token = sessionStorage.getItem("mrroc-token") || "";

async function api(method, path, body) {
  const headers = { "X-Mrroc-Request": "1" };
  if (token) headers["Authorization"] = "Bearer " + token;
  if (method === "POST" && body === undefined) body = {};
  if (body !== undefined) headers["Content-Type"] = "application/json";
  const response = await fetch(path, {
    method, headers, body: body === undefined ? undefined : JSON.stringify(body),
  });
  let data = {};
  try { data = await response.json(); } catch (e) { data = { error: "HTTP " + response.status }; }
  if (!response.ok && !data.error) data.error = "HTTP " + response.status;
  data.httpStatus = response.status;
  return data;
}

function $(id) { return document.getElementById(id); }
function fmt(x, digits) { return (typeof x === "number" && isFinite(x)) ? x.toFixed(digits) : "–"; }
function duration(s) {
  if (typeof s !== "number" || !isFinite(s)) return "–";
  if (s < 60) return s.toFixed(1) + " s";
  if (s < 3600) return Math.floor(s / 60) + " min " + Math.floor(s % 60) + " s";
  return Math.floor(s / 3600) + " h " + Math.floor((s % 3600) / 60) + " min";
}
function showResult(element, data, okText) {
  element.classList.toggle("error", !!data.error);
  element.textContent = data.error ? data.error : (okText || data.text || "");
}

// ---------------------------------------------------------------------------------------------
// Task panel

let lastState = null;
let commandsSent = 0;
const robots = new Map();  // name -> { element, series, lastStep, info }

function updateMp(mp) {
  const state = mp.state || "NO MP";
  const stateElement = $("mp-state");
  stateElement.textContent = state;
  stateElement.className = "state " + state;
  $("mp-task").textContent = mp.task || "–";
  $("mp-runs").textContent = mp.runs !== undefined ? mp.runs : "–";
  const running = state === "RUNNING" || state === "PAUSED" || state === "STOPPING";
  $("mp-elapsed").textContent = running && mp.started_utime
    ? duration(Date.now() / 1000 - mp.started_utime / 1e6) : "–";
  $("mp-text").textContent = mp.available ? (mp.text || "") : (mp.error || "");
  $("mp-text").classList.toggle("error", !mp.available || state === "FAILED");
  const can = {
    start: mp.available && (state === "IDLE" || state === "FINISHED" || state === "FAILED"),
    pause: state === "RUNNING",
    resume: state === "PAUSED",
    stop: state === "RUNNING" || state === "PAUSED",
    terminate: !!mp.available && state !== "TERMINATING",
  };
  for (const [command, enabled] of Object.entries(can)) $("cmd-" + command).disabled = !enabled;
}

for (const button of document.querySelectorAll("#mp-panel button[data-command]")) {
  button.addEventListener("click", async () => {
    const command = button.dataset.command;
    $("command-result").textContent = command.toUpperCase() + " ...";
    ++commandsSent;
    const data = await api("POST", "/api/command/" + command);
    ++commandsSent;  // a state poll that began before this answer is older than it
    showResult($("command-result"), data,
      command.toUpperCase() + " accepted: MP " + data.state + (data.text ? " (" + data.text + ")" : ""));
    if (data.state) updateMp(Object.assign({ available: true }, data));
  });
}

// A red banner names the robots that did not confirm the stop (or its release) in time.
function showEstopConfirmation(data, engage) {
  const banner = $("estop-banner");
  const missing = data.unconfirmed || [];
  if (missing.length > 0) {
    banner.textContent = (engage ? "EMERGENCY STOP NOT CONFIRMED by " : "RELEASE NOT CONFIRMED by ") +
      missing.join(", ") + " within " + data.deadline_ms + " ms: " +
      (engage ? "check the robot and use the hard-wired emergency stop" : "the robot may still be stopped");
    banner.hidden = false;
  } else if (!data.latched_by) {
    // Every robot obeyed, but no latch holder named this command: a robot that restarts, or
    // missed it, would not know.
    banner.textContent = (engage ? "EMERGENCY STOP NOT LATCHED" : "RELEASE NOT LATCHED") +
      ": no latch holder (mrroc-launch) announced it; " +
      (engage ? "a robot that restarts may move: keep the hard-wired emergency stop at hand"
              : "a robot that restarts stays stopped");
    banner.hidden = false;
  } else {
    banner.hidden = true;
    banner.textContent = "";
  }
}
$("estop").addEventListener("click", async () => {
  const data = await api("POST", "/api/estop", {});
  const steps = Object.entries(data.servo_step_at_send || {})
    .map(([robot, step]) => robot + " at servo step " + step).join(", ");
  showResult($("command-result"), data, data.text + (steps ? " (sent: " + steps + ")" : ""));
  showEstopConfirmation(data, true);
});
$("release").addEventListener("click", async () => {
  const data = await api("POST", "/api/release", {});
  showResult($("command-result"), data);
  showEstopConfirmation(data, false);
});

// ---------------------------------------------------------------------------------------------
// Process table: the launcher's when it runs, else the processes' own status messages

function updateProcesses(state) {
  const body = document.querySelector("#processes tbody");
  const rows = [];
  if (state.launch) {
    $("processes-source").textContent =
      "from the launcher (pid " + state.launch.launcher_pid + ", set " + state.launch.state + ")";
    for (const p of state.launch.processes)
      rows.push([p.name, p.group, p.host, p.state, p.pid || "", fmt(p.cpu_percent, 1),
                 p.rss_kb ? (p.rss_kb / 1024).toFixed(1) + " MiB" : "", p.restarts,
                 duration(p.uptime_s)]);
  } else {
    $("processes-source").textContent = "from the processes' status messages (no launcher)";
    for (const p of state.processes) {
      const silent = p.silent_s > 3 ? " (silent " + p.silent_s.toFixed(0) + " s)" : "";
      rows.push([p.name, p.name.split("/")[0], "", p.state + silent, p.pid, "", "", "",
                 duration(p.uptime_s)]);
    }
  }
  body.replaceChildren(...rows.map((cells) => {
    const tr = document.createElement("tr");
    tr.dataset.process = cells[0];
    cells.forEach((value, i) => {
      const td = document.createElement("td");
      td.textContent = value;
      if (i === 3) td.className = "proc-state " + String(value).split(" ")[0].toLowerCase();
      if (i >= 4) td.classList.add("num");
      tr.appendChild(td);
    });
    return tr;
  }));
}

// ---------------------------------------------------------------------------------------------
// Robots: flags, joints, jogging, teach-in, plots

function createRobot(info) {
  const element = $("robot-template").content.firstElementChild.cloneNode(true);
  element.dataset.robot = info.name;
  element.querySelector(".robot-name").textContent = info.name;
  element.querySelector(".teach-file").value = info.name + ".traj";
  const body = element.querySelector(".joints tbody");
  info.joint_names.forEach((joint, axis) => {
    // Names and units come from the robot's model files: text, never markup.
    const tr = document.createElement("tr");
    const unit = (info.units && info.units[axis]) || "rad";
    const cell = (className, text) => {
      const td = document.createElement("td");
      if (className) td.className = className;
      if (text !== undefined) td.textContent = text;
      tr.appendChild(td);
      return td;
    };
    cell("", String(axis));
    cell("joint-name", String(joint));
    cell("unit", String(unit));
    cell("num q");
    cell("num dq");
    cell("num qd");
    cell("num", `${fmt(info.lower_limits[axis], 2)} .. ${fmt(info.upper_limits[axis], 2)}`);
    const buttons = cell("");
    for (const [cls, label, direction] of [["jog-minus", "\u2212", -1], ["jog-plus", "+", 1]]) {
      const button = document.createElement("button");
      button.className = cls;
      button.title = `jog axis ${axis} by ${direction < 0 ? "-" : "+"}step`;
      button.textContent = label;
      button.addEventListener("click", () => jog(info.name, axis, direction));
      if (direction > 0) buttons.append(" ");
      buttons.appendChild(button);
    }
    body.appendChild(tr);
  });
  if (info.cartesian) {
    const tool = element.querySelector(".tool-jog");
    tool.hidden = false;
    ["x", "y", "z", "rx", "ry", "rz"].forEach((name, axis) => {
      for (const [label, direction] of [["\u2212", -1], ["+", 1]]) {
        const button = document.createElement("button");
        button.className = "tool-jog-button";
        button.dataset.axis = axis;
        button.dataset.direction = direction;
        button.textContent = name + label;
        button.title = (axis < 3 ? "move the tool along its own " : "turn the tool about its own ") +
          name.slice(-1) + " axis";
        button.addEventListener("click", () => jogTool(info.name, axis, direction));
        tool.querySelector(".tool-buttons").appendChild(button);
      }
    });
  }
  element.querySelector(".jog-unit").textContent =
    [...new Set(info.units || ["rad"])].join(" or ");
  element.querySelector(".synchronise").addEventListener("click", async () => {
    const result = element.querySelector(".jog-result");
    result.classList.remove("error");
    result.textContent = "synchronising " + info.name + " ...";
    showResult(result, await api("POST", "/api/synchronise", { robot: info.name }));
  });
  element.querySelector(".teach").addEventListener("click", async () => {
    const data = await api("POST", "/api/teach",
      { robot: info.name, file: element.querySelector(".teach-file").value });
    showResult(element.querySelector(".jog-result"), data);
  });
  $("robots").appendChild(element);
  const robot = { element, info, lastStep: 0, samples: [] };
  robots.set(info.name, robot);
  return robot;
}

async function jog(name, axis, direction) {
  const robot = robots.get(name);
  const result = robot.element.querySelector(".jog-result");
  const step = parseFloat(robot.element.querySelector(".jog-step").value);
  result.classList.remove("error");
  result.textContent = "jogging axis " + axis + " ...";
  const data = await api("POST", "/api/jog", { robot: name, axis, direction, step_rad: step });
  showResult(result, data);
}

async function jogTool(name, axis, direction) {
  const robot = robots.get(name);
  const result = robot.element.querySelector(".jog-result");
  const step = parseFloat(robot.element.querySelector(axis < 3 ? ".tool-step-m" : ".tool-step-rad").value);
  result.classList.remove("error");
  result.textContent = "jogging the tool frame ...";
  const data = await api("POST", "/api/jog", { robot: name, space: "tool", axis, direction, step });
  showResult(result, data);
}

function updateRobot(info) {
  const robot = robots.get(info.name) || createRobot(info);
  const s = info.state;
  const e = robot.element;
  for (const flag of e.querySelectorAll(".flag"))
    flag.classList.toggle("on", !!(s && s[flag.dataset.flag]));
  e.querySelector(".robot-error").textContent = s ? (s.error || "") : "no robot_state_t from its EDP";
  e.querySelector(".robot-error").classList.toggle("error", !s || !!s.error);
  e.querySelector(".servo").textContent = s
    ? `servo step ${s.servo_step}, period ${fmt(s.servo_period_s * 1e3, 1)} ms, lateness mean ${fmt(s.lateness_mean_us, 0)} us / max ${fmt(s.lateness_max_us, 0)} us, overruns ${s.overruns}` +
      (s.age_s > 1 ? `, last state ${s.age_s.toFixed(0)} s ago` : "")
    : "";
  e.querySelector(".synchronise").disabled = !s || !!s.synchronised;
  // Before SYNCHRO the EDP takes relative joint moves only, at reduced limits (docs/edp.md).
  e.querySelector(".jog-mode").textContent = s && !s.synchronised
    ? "UNSYNCHRONISED: joint jogs at reduced limits, raw axis positions; tool jogs need Synchronise"
    : "";
  const rows = e.querySelectorAll(".joints tbody tr");
  rows.forEach((tr, axis) => {
    tr.querySelector(".q").textContent = s ? fmt(s.q[axis], 4) : "–";
    tr.querySelector(".dq").textContent = s ? fmt(s.dq[axis], 4) : "–";
    tr.querySelector(".qd").textContent = s ? fmt(s.q_desired[axis], 4) : "–";
  });
}

async function pollSamples() {
  for (const robot of robots.values()) {
    const data = await api("GET", `/api/robots/${robot.info.name}/samples?after=${robot.lastStep}`);
    if (data.error || !data.samples) continue;
    if (data.samples.length && data.samples[0].step < robot.lastStep) robot.samples = [];
    for (const sample of data.samples) robot.samples.push(sample);
    if (robot.samples.length) robot.lastStep = robot.samples[robot.samples.length - 1].step;
    const newest = robot.samples.length ? robot.samples[robot.samples.length - 1].utime : 0;
    while (robot.samples.length && robot.samples[0].utime < newest - PLOT_WINDOW_S * 1e6)
      robot.samples.shift();
    drawPlots(robot);
  }
}

function drawPlot(canvas, samples, series, labels) {
  const ctx = canvas.getContext("2d");
  const w = canvas.width, h = canvas.height, left = 44, bottom = 16;
  ctx.clearRect(0, 0, w, h);
  if (samples.length < 2) return;
  const t1 = samples[samples.length - 1].utime / 1e6, t0 = t1 - PLOT_WINDOW_S;
  let lo = Infinity, hi = -Infinity;
  for (const s of samples) for (const f of series) { const v = f(s); if (isFinite(v)) { lo = Math.min(lo, v); hi = Math.max(hi, v); } }
  if (!isFinite(lo)) return;
  if (hi - lo < 1e-3) { lo -= 0.5e-3; hi += 0.5e-3; }
  const pad = (hi - lo) * 0.08, positive = lo >= 0;
  lo -= pad; hi += pad;
  if (positive) lo = Math.max(lo, 0);
  const x = (t) => left + (t - t0) / PLOT_WINDOW_S * (w - left - 4);
  const y = (v) => (h - bottom) - (v - lo) / (hi - lo) * (h - bottom - 4);
  ctx.strokeStyle = "#d0d7de"; ctx.fillStyle = "#57606a"; ctx.font = "10px sans-serif"; ctx.lineWidth = 1;
  for (let i = 0; i <= 4; ++i) {
    const v = lo + (hi - lo) * i / 4;
    ctx.beginPath(); ctx.moveTo(left, y(v)); ctx.lineTo(w, y(v)); ctx.stroke();
    const span = hi - lo;
    ctx.fillText(span > 20 ? v.toFixed(0) : span > 0.05 ? v.toFixed(2) : v.toExponential(1), 2, y(v) + 3);
  }
  for (let s = 0; s <= PLOT_WINDOW_S; s += 5) ctx.fillText("-" + (PLOT_WINDOW_S - s) + " s", x(t0 + s) - 10, h - 3);
  series.forEach((f, i) => {
    ctx.strokeStyle = COLOURS[i % COLOURS.length]; ctx.lineWidth = 1.4; ctx.beginPath();
    let first = true;
    for (const s of samples) {
      const v = f(s); if (!isFinite(v)) continue;
      if (first) { ctx.moveTo(x(s.utime / 1e6), y(v)); first = false; } else ctx.lineTo(x(s.utime / 1e6), y(v));
    }
    ctx.stroke();
    ctx.fillStyle = COLOURS[i % COLOURS.length];
    ctx.fillText(labels[i], left + 6 + i * 80, 11);
  });
}

function drawPlots(robot) {
  const e = robot.element, names = robot.info.joint_names;
  drawPlot(e.querySelector(".plot-q"), robot.samples, names.map((_, i) => (s) => s.q[i]), names);
  drawPlot(e.querySelector(".plot-dq"), robot.samples, names.map((_, i) => (s) => s.dq[i]), names);
  drawPlot(e.querySelector(".plot-lateness"), robot.samples,
    [(s) => s.lateness_mean_us, (s) => s.lateness_max_us], ["mean", "max"]);
}

// ---------------------------------------------------------------------------------------------
// SRP messages: the history first (the SRP's, merged by the server), then live ones

const log = { entries: [], last: 0, epoch: null };

function renderLog() {
  const min = parseInt($("log-severity").value, 10);
  const shown = log.entries.filter((m) => m.severity >= min);
  const box = $("log");
  const atBottom = box.scrollTop + box.clientHeight >= box.scrollHeight - 4;
  box.replaceChildren(...shown.slice(-1000).map((m) => {
    const div = document.createElement("div");
    div.className = "msg s" + m.severity;
    for (const [i, cls] of ["time", "proc", "sev", "text"].entries()) {
      const span = document.createElement("span");
      span.className = cls;
      if (i > 0) div.append(" ");
      div.appendChild(span);
    }
    div.querySelector(".time").textContent = m.time;
    div.querySelector(".proc").textContent = m.process.padEnd(10);
    div.querySelector(".sev").textContent = m.severity_name;
    div.querySelector(".text").textContent = (m.code ? "[" + m.code + "] " : "") + m.text;
    return div;
  }));
  if (atBottom) box.scrollTop = box.scrollHeight;
  $("log-count").textContent = `${shown.length} of ${log.entries.length} messages`;
}
$("log-severity").addEventListener("change", renderLog);

async function pollLog() {
  const data = await api("GET", `/api/srp?after=${log.last}&min_severity=0&max=5000`);
  if (data.error) return;
  if (log.epoch !== null && data.epoch !== log.epoch) {  // the history was merged in: reload
    log.entries = []; log.last = 0; log.epoch = data.epoch;
    return pollLog();
  }
  log.epoch = data.epoch;
  if (data.messages.length) {
    log.entries.push(...data.messages);
    log.last = data.messages[data.messages.length - 1].n;
    if (log.entries.length > 5000) log.entries.splice(0, log.entries.length - 5000);
    renderLog();
  } else if (log.entries.length === 0) {
    renderLog();
  }
}

// ---------------------------------------------------------------------------------------------

async function pollState() {
  let state;
  const sentBefore = commandsSent;
  try {
    state = await api("GET", "/api/state");
  } catch (e) {
    state = { error: "no connection", httpStatus: 0 };
  }
  const connection = $("connection");
  if (state.error) {
    connection.textContent = state.httpStatus === 401
      ? "token needed: open the page as /?token=TOKEN (mrroc-ui serve names the file that holds it)"
      : "no connection to the console";
    connection.className = "badge bad";
    return;
  }
  connection.textContent = "connected";
  connection.className = "badge ok";
  $("set-name").textContent = state.set;
  document.title = "mrroc " + state.set;
  lastState = state;
  if (sentBefore === commandsSent) updateMp(state.mp);
  updateProcesses(state);
  for (const robot of state.robots) updateRobot(robot);
}

function loop(f, period_ms) {
  const run = async () => {
    try { await f(); } catch (e) { /* the server is away: try again */ }
    setTimeout(run, period_ms);
  };
  run();
}

loop(pollState, 200);
loop(pollSamples, 250);
loop(pollLog, 500);
