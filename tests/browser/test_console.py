#!/usr/bin/python3
"""The web operator console in headless Chromium (Selenium), on the real process set.

Runs configs/console-demo.toml (SRP, EDP with MuJoCo, ECP, MP waiting for the operator, and the
console `mrroc-ui serve`, started by mrroc-launch because [ui] web = true) inside
scripts/netns-run, reads the API token the console generated (no [ui] token_file) from the file
whose path it prints (its standard output is the launcher's pipe, so it does not print the token;
no output line and no log file holds it; a request without it gets 401), opens the console with it
and, through the page's buttons:
  Start -> MP RUNNING, the joints change -> FINISHED;
  Start, Pause -> PAUSED and the robot stands still (|dq| of the EDP's robot_state_t);
  Resume, Emergency stop during a motion -> standstill within the bound computed from the
  IRb-6's velocity and deceleration limits and the servo period; Release;
  jog one axis, Record pose twice (the file parses with the library's trajectory parser);
  Terminate -> the set ends (launcher exit code 0) and no mrroc process is left.
The 3D view: it loads the IRb-6 from its URDF (GET /api/robots/irb6/urdf, which needs the token;
its libraries come from the console's /vendor/), draws it visibly, and while the robot moves its
drawn pose (read back with window.mrrocView) changes, is updated with at least VIEW_MIN_RATE robot
states per second (VIEW_MIN_RATE_BUSY on a machine loaded beyond VIEW_BUSY_LOAD) and drawn with at
least VIEW_MIN_FRAMES frames per second,
shows the joint values of the robot state of the same servo step within VIEW_Q_TOL, its links
stand where the URDF's forward kinematics (urdf_fk.py, computed here) puts them within
VIEW_POSE_TOL, and the commanded pose's ghost shows q_desired of that state.
Screenshots of every stage: <artifacts>/NN-stage.png (and view-running.png, the 3D view alone).
"""
import argparse
import http.client
import json
import math
import os
import re
import shutil
import subprocess
import sys
import tempfile
import threading
import time
import tomllib
import urllib.request

from selenium import webdriver
from selenium.webdriver.chrome.service import Service
from selenium.webdriver.common.by import By
from selenium.webdriver.support.ui import Select

sys.dont_write_bytecode = True  # importing urdf_fk leaves no __pycache__ in the source tree
import urdf_fk  # noqa: E402 (beside this file)

URL = "http://127.0.0.1:8080"
# The console's API token, read from the file whose path it prints (set in main()).
TOKEN = ""
# What the console prints when its standard output is not a terminal: the URL without the token,
# and where the token is.
URL_WITHOUT_TOKEN = re.compile(r"web console of set 'console-demo' at http://127\.0\.0\.1:8080/ "
                               r"\(open it once as http://127\.0\.0\.1:8080/\?token=TOKEN", re.M)
TOKEN_FILE_LINE = re.compile(r"mrroc-ui: API token in (\S+) \(removed when the console ends\)$",
                             re.M)
STANDSTILL_DQ = 0.01   # rad/s: every |dq| below this is a standstill
# The poses and velocity scale of configs/console-demo.toml's task, for the emergency stop's choice
# of a motion with ESTOP_TIME_LEFT_S left (read in main()).
DEMO_POSES = []
DEMO_VELOCITY_SCALE = 1.0
ESTOP_TIME_LEFT_S = 1.0
PAUSE_STILL_DQ = 0.01  # rad/s while paused
VIEW_Q_TOL = 1e-6      # rad: a drawn joint value vs. the robot state of the same servo step
VIEW_POSE_TOL = 1e-6   # m, and rotation matrix elements: a drawn link vs. the URDF's kinematics
VIEW_MIN_RATE = 30     # robot states applied to the drawn robot per second while it moves
# On a machine whose load average exceeds VIEW_BUSY_LOAD per CPU the page's script gets too little
# of it to take 30 states a second, and the bound is VIEW_MIN_RATE_BUSY (said in the output).
VIEW_BUSY_LOAD = 1.5
VIEW_MIN_RATE_BUSY = 15
# Frames: the page draws on the CPU here (SwiftShader), beside the set's real-time threads on two
# cores (ctest runs the browser tests alone: RUN_SERIAL); measured 28-33 frames per second with
# one test beside it, 20-23 in a CI run where another test beside it left 25 states a second,
# 16 with two busy loops. A GPU draws at the display's rate.
VIEW_MIN_FRAMES = 15
VIEW_MIN_TRAVEL = 0.05  # m: the drawn wrist moves at least this far while watched

failures = []


def check(condition, what):
    print(("ok:   " if condition else "FAIL: ") + what, flush=True)
    if not condition:
        failures.append(what)
    return condition


def api(path, body=None):
    request = urllib.request.Request(URL + path)
    request.add_header("Authorization", "Bearer " + TOKEN)
    if body is not None:
        request.data = json.dumps(body).encode()
        request.add_header("X-Mrroc-Request", "1")
        request.add_header("Content-Type", "application/json")
    try:
        with urllib.request.urlopen(request, timeout=5) as response:
            return json.load(response)
    except urllib.error.HTTPError as e:
        return json.load(e)


def api_raw(path, data, content_type="application/json"):
    """POSTs raw bytes; returns (HTTP status, parsed JSON answer or None)."""
    request = urllib.request.Request(URL + path, data=data, method="POST")
    request.add_header("Authorization", "Bearer " + TOKEN)
    request.add_header("X-Mrroc-Request", "1")
    request.add_header("Content-Type", content_type)
    try:
        with urllib.request.urlopen(request, timeout=5) as response:
            status, text = response.status, response.read()
    except urllib.error.HTTPError as e:
        status, text = e.code, e.read()
    try:
        return status, json.loads(text)
    except ValueError:
        return status, None


def check_hostile_requests():
    """Malformed and out-of-range request bodies get a 4xx with a clear text; nothing moves."""
    before = api("/api/state")["robots"][0]["state"]
    cases = [
        ("/api/jog", b"{", 400, "not a JSON object"),
        ("/api/jog", b"[1, 2]", 400, "not a JSON object"),
        ("/api/jog", b"\xff\xfe\x00garbage", 400, "not a JSON object"),
        ("/api/jog", b'{"robot": 5, "axis": 0, "step_rad": 0.01}', 400, "request body"),
        ("/api/jog", b'{"robot": "irb6", "axis": "0", "step_rad": 0.01}', 400, "integer 'axis'"),
        ("/api/jog", b'{"robot": "irb6", "axis": 99, "step_rad": 0.01}', 400, "axis 99 is out of range"),
        ("/api/jog", b'{"robot": "irb6", "axis": -1, "step_rad": 0.01}', 400, "out of range"),
        ("/api/jog", b'{"robot": "irb6", "axis": 0, "step_rad": 1e308}', 400, "rad is outside"),
        ("/api/jog", b'{"robot": "irb6", "axis": 0, "step_rad": -0.01}', 400, "rad is outside"),
        ("/api/jog", b'{"robot": "irb6", "axis": 0, "step_rad": 0.01, "direction": 2}', 400,
         "neither +1 nor -1"),
        ("/api/jog", b'{"robot": "irb6", "axis": 0, "step_rad": 0.01, "direction": 1.5}', 400,
         "must be +1 or -1"),
        ("/api/jog", b'{"robot": "nope", "axis": 0, "step_rad": 0.01}', 404, "no robot 'nope'"),
        ("/api/teach", b'{"robot": "irb6", "file": "../escape.traj"}', 400, "not a plain file name"),
        ("/api/teach", b'{"robot": "irb6", "file": 7}', 400, "request body"),
        ("/api/release", b"not json", 400, "not a JSON object"),
        ("/api/command/launch", b"{}", 404, ""),
    ]
    for path, data, status, words in cases:
        got, answer = api_raw(path, data)
        text = (answer or {}).get("error", "")
        check(got == status and words in text,
              f"POST {path} {data[:60]!r}: HTTP {got} (expected {status}) '{text}'")
    after = api("/api/state")
    moved = max(abs(a - b) for a, b in zip(after["robots"][0]["state"]["q"], before["q"]))
    check(moved < 1e-4 and after["mp"]["state"] == "IDLE",
          f"after the hostile requests nothing moved ({moved:.1e} rad) and the MP is still IDLE")


def check_hostile_estop():
    """An emergency stop whose body cannot be understood still stops every robot."""
    for data in [b"{", b'{"robot": 5}', b'{"robot": "nope"}']:
        got, answer = api_raw("/api/estop", data)
        answer = answer or {}
        check(got == 400 and answer.get("ok") is True and "every robot" in answer.get("error", ""),
              f"POST /api/estop {data!r}: HTTP {got}, stops every robot: {answer.get('error')}")
    state = api("/api/state")["robots"][0]["state"]
    check(state["estop"], "the emergency stop is still engaged")


def get_text(path, token=True):
    """GET path (with the token unless not `token`); returns (HTTP status, content type, text)."""
    connection = http.client.HTTPConnection("127.0.0.1", 8080, timeout=5)
    headers = {"Authorization": "Bearer " + TOKEN} if token else {}
    connection.request("GET", path, headers=headers)
    response = connection.getresponse()
    result = response.status, response.getheader("Content-Type", ""), response.read().decode()
    connection.close()
    return result


def view(driver, expression):
    return driver.execute_script("return window.mrrocView && " + expression)


def drawn_pose_error(urdf, joint_names, drawn):
    """The largest differences between the drawn links and the URDF's forward kinematics at the
    drawn joint values: (position [m], rotation [-])."""
    fk = urdf.link_poses(dict(zip(joint_names, drawn["j"]["q"])))
    errors = [urdf_fk.pose_error(fk[link], drawn["p"][link]) for link in urdf.links]
    return max(e[0] for e in errors), max(e[1] for e in errors)


READ_VIEW = ("const v = window.mrrocView; return {j: v.jointValues('irb6'), "
             "p: v.linkPoses('irb6'), s: v.stats()};")


def check_view_loaded(driver, source_dir):
    """The 3D view has the IRb-6 from its URDF, drawn visibly, where the kinematics put it; the
    routes it uses keep the token rules; its libraries are the console's own."""
    ready = wait_for("the 3D view loaded the IRb-6 and draws its robot state", lambda: view(
        driver, "window.mrrocView.ready && window.mrrocView.jointValues('irb6').step !== null"), 30)
    if not ready:
        print("3D view: " + driver.find_element(By.ID, "view-note").text, flush=True)
        return None
    check(view(driver, "window.mrrocView.robots()") == ["irb6"],
          "the 3D view draws the set's robot")
    urdf_text = open(os.path.join(source_dir, "robots", "irb6", "irb6.urdf")).read()
    status, kind, text = get_text("/api/robots/irb6/urdf")
    check(status == 200 and "xml" in kind and text == urdf_text,
          f"GET /api/robots/irb6/urdf: HTTP {status} {kind}, the text of robots/irb6/irb6.urdf")
    status, _, _ = get_text("/api/robots/irb6/urdf", token=False)
    check(status == 401, f"the URDF without the token: 401 (got {status})")
    status, _, text = get_text("/api/robots/nope/urdf")
    check(status == 404 and "nope" in text, f"the URDF of an unknown robot: 404 (got {status})")
    status, kind, text = get_text("/vendor/three/build/three.module.js", token=False)
    check(status == 200 and "javascript" in kind and "REVISION" in text,
          f"three.js is served by the console itself: HTTP {status} {kind}, {len(text)} bytes")
    for bad in ["/vendor/../CMakeLists.txt", "/vendor/three/%2e%2e/%2e%2e/package.json",
                "/vendor/.hidden", "/vendor/three/build/none.js"]:
        status, _, _ = get_text(bad, token=False)
        check(status in (400, 404), f"GET {bad}: refused, 400 or 404 (got {status})")
    pixels = view(driver, "window.mrrocView.visiblePixels()")
    share = pixels["coloured"] / max(1, pixels["width"] * pixels["height"])
    check(share > 0.01, f"the robot is visible in the 3D view: {pixels['coloured']} coloured "
          f"pixels of {pixels['width']}x{pixels['height']} ({share:.1%} > 1%)")
    urdf = urdf_fk.Urdf(urdf_text)
    names = api("/api/state")["robots"][0]["joint_names"]
    drawn = driver.execute_script(READ_VIEW)
    dp, dr = drawn_pose_error(urdf, names, drawn)
    check(dp <= VIEW_POSE_TOL and dr <= VIEW_POSE_TOL,
          f"at rest the drawn links stand where the URDF's kinematics puts them: {dp:.1e} m, "
          f"{dr:.1e} <= {VIEW_POSE_TOL}")
    return urdf, names


def watch_view(driver, urdf, names, seconds):
    """Reads the drawn pose every 150 ms for `seconds` while /api/joints is polled alongside;
    checks what was drawn against the robot states."""
    joints = {}  # servo step -> (q, q_desired), from /api/joints
    stop = threading.Event()

    def poll():
        while not stop.is_set():
            try:
                r = api("/api/joints")["robots"][0]
                if r["step"] is not None:
                    joints[r["step"]] = (r["q"], r["q_desired"])
            except Exception:
                pass
            time.sleep(0.025)
    poller = threading.Thread(target=poll, daemon=True)
    poller.start()
    records = []
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        records.append(driver.execute_script(READ_VIEW))
        time.sleep(0.15)
    stop.set()
    poller.join()
    steps = [r["j"]["step"] for r in records]
    samples = {s["step"]: s["q"] for s in samples_after(min(steps) - 1)}
    matched = [r for r in records if r["j"]["step"] in samples]
    q_error = max((abs(a - b) for r in matched
                   for a, b in zip(r["j"]["q"], samples[r["j"]["step"]])), default=math.inf)
    check(len(matched) >= 0.9 * len(records) and q_error <= VIEW_Q_TOL,
          f"3D view: {len(matched)} of {len(records)} drawn poses read back found in the robot "
          f"states of their servo step; drawn joints differ from them by at most {q_error:.1e} "
          f"rad <= {VIEW_Q_TOL}")
    if len(matched) < len(records):
        missing = sorted(r["j"]["step"] for r in records if r["j"]["step"] not in samples)
        print(f"3D view: drawn servo steps not among the console's samples {missing}; samples "
              f"{min(samples, default=None)}..{max(samples, default=None)} ({len(samples)})",
              flush=True)
    pose_errors = [drawn_pose_error(urdf, names, r) for r in records]
    dp = max(e[0] for e in pose_errors)
    dr = max(e[1] for e in pose_errors)
    check(dp <= VIEW_POSE_TOL and dr <= VIEW_POSE_TOL,
          f"3D view: every drawn link stands where the URDF's kinematics puts it for the drawn "
          f"joints: {dp:.1e} m, {dr:.1e} <= {VIEW_POSE_TOL}")
    wrist = [r["p"]["roll_link"]["position"] for r in records]
    travel = max(math.dist(w, wrist[0]) for w in wrist)
    check(len(set(steps)) >= 8 and travel >= VIEW_MIN_TRAVEL,
          f"3D view: the drawn pose changes: {len(set(steps))} different poses read back in "
          f"{seconds} s, "
          f"the drawn wrist moved up to {travel:.3f} m >= {VIEW_MIN_TRAVEL} m")
    source = [st for st in joints if min(steps) <= st <= max(steps)]
    polled = records[-1]["s"]["polls"] - records[0]["s"]["polls"]
    print(f"3D view: the console had {len(source)} robot states in the window (read from "
          f"/api/joints every 25 ms), the page polled {polled} times", flush=True)
    later = records[len(records) // 3:]  # the rates count the last second
    states = sorted(r["s"]["states_per_s"]["irb6"] for r in later)
    frames = sorted(r["s"]["frames_per_s"] for r in later)
    print(f"3D view: robot states drawn per second {states}, frames per second {frames}",
          flush=True)
    load = os.getloadavg()[0]
    cpus = os.cpu_count() or 1
    bound = VIEW_MIN_RATE if load <= VIEW_BUSY_LOAD * cpus else VIEW_MIN_RATE_BUSY
    why = ("" if bound == VIEW_MIN_RATE else
           f" (the machine is busy: load average {load:.1f} on {cpus} CPUs > {VIEW_BUSY_LOAD} per "
           f"CPU, the bound is {VIEW_MIN_RATE_BUSY} instead of {VIEW_MIN_RATE})")
    check(states[len(states) // 2] >= bound,
          f"3D view: median {states[len(states) // 2]} robot states drawn per second >= "
          f"{bound}{why}")
    check(frames[len(frames) // 2] >= VIEW_MIN_FRAMES,
          f"3D view: median {frames[len(frames) // 2]} frames per second >= {VIEW_MIN_FRAMES} "
          f"(drawn on the CPU)")
    ghosts = [r for r in records if r["j"]["ghost_visible"] and r["j"]["step"] in joints]
    ghost_error = max((abs(a - b) for r in ghosts
                       for a, b in zip(r["j"]["q_desired"], joints[r["j"]["step"]][1])),
                      default=math.inf)
    check(len(ghosts) >= 3 and ghost_error <= VIEW_Q_TOL,
          f"3D view: the commanded pose's ghost shown in {len(ghosts)} readings whose robot state "
          f"was also read from /api/joints; its joints differ from q_desired by at most "
          f"{ghost_error:.1e} rad <= {VIEW_Q_TOL}")


def wait_for(what, predicate, timeout_s, period_s=0.05):
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        try:
            value = predicate()
            if value:
                return value
        except Exception:  # the server may not answer yet
            pass
        time.sleep(period_s)
    check(False, f"{what} within {timeout_s} s")
    return None


class LaunchedSet:
    """mrroc-launch on a config, its output collected (and echoed with a prefix)."""

    def __init__(self, bin_dir, config):
        self.lines = []
        self.process = subprocess.Popen([os.path.join(bin_dir, "mrroc-launch"), config],
                                        stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                        text=True)
        self.reader = threading.Thread(target=self._read, daemon=True)
        self.reader.start()

    def _read(self):
        for line in self.process.stdout:
            self.lines.append(line.rstrip("\n"))
            print("  | " + line.rstrip("\n"), flush=True)

    def output(self):
        return "\n".join(self.lines)


def make_config(source_dir, artifacts):
    """configs/console-demo.toml with absolute paths and teach_dir in the artifacts folder."""
    text = open(os.path.join(source_dir, "configs", "console-demo.toml")).read()
    text = text.replace('model = "../robots/irb6"',
                        f'model = "{os.path.join(source_dir, "robots", "irb6")}"')
    text = re.sub(r'^# teach_dir = .*$', f'teach_dir = "{os.path.join(artifacts, "taught")}"',
                  text, flags=re.M)
    # Log files of every process, where the test looks for the token afterwards.
    text += f'\n[launch]\nlog_dir = "{os.path.join(artifacts, "logs")}"\n'
    path = os.path.join(artifacts, "console-demo.toml")
    with open(path, "w") as f:
        f.write(text)
    return path


def estop_bound_steps(source_dir, servo_period_s):
    """Servo steps from the emergency stop to a standstill, at most: the slowest axis' ramp from
    its maximum velocity at its maximum deceleration, plus one robot_state_t period (10 steps:
    the state that shows the standstill comes up to 20 ms later) plus 25 steps (50 ms) for the
    message's way to the EDP and the measured velocity settling behind the commanded one."""
    with open(os.path.join(source_dir, "robots", "irb6", "parameters.toml"), "rb") as f:
        robot = tomllib.load(f)["robot"]
    ramps = [v / a / servo_period_s for v, a in zip(robot["max_joint_velocity"],
                                                      robot["max_joint_acceleration"])]
    ramp = math.ceil(max(ramps))
    return ramp + 10 + 25, ramp, robot


def click(driver, element_id):
    """Clicks a button once the page has enabled it."""
    button = driver.find_element(By.ID, element_id)
    wait_for(f"button {element_id} enabled", button.is_enabled, 5, 0.02)
    button.click()


def process_names(driver):
    """The process table's names, read in one go (the table is rebuilt every 200 ms)."""
    return driver.execute_script(
        "return Array.from(document.querySelectorAll('#processes tbody tr'))"
        ".map(r => r.dataset.process)")


def mp_state(driver):
    return driver.find_element(By.ID, "mp-state").text


def joint_cells(driver, cls):
    cells = driver.find_elements(By.CSS_SELECTOR, f'.robot[data-robot="irb6"] .joints td.{cls}')
    return [float(c.text) if c.text not in ("", "–") else None for c in cells]


def samples_after(step):
    return api(f"/api/robots/irb6/samples?after={step}")["samples"]


def status_and_error(url, headers=None):
    """GET url; returns (HTTP status, the answer's "error" or None)."""
    request = urllib.request.Request(url, headers=headers or {})
    try:
        with urllib.request.urlopen(request, timeout=5) as response:
            status, text = response.status, response.read()
    except urllib.error.HTTPError as e:
        status, text = e.code, e.read()
    try:
        return status, json.loads(text).get("error")
    except ValueError:
        return status, None


def check_generated_token(token_file):
    """The console without [ui] token_file: its token is in token_file (mode 0600), a request
    without it gets 401 saying where it is, and the SRP's log does not hold it."""
    mode = os.stat(token_file).st_mode & 0o777 if os.path.exists(token_file) else None
    check(mode == 0o600, f"the generated token is in {token_file}, mode 0600 (got {mode and oct(mode)})")
    if mode is not None:
        check(open(token_file).read() == TOKEN + "\n", "the token file holds the token read from it at the start")
    status, error = status_and_error(URL + "/api/state")
    check(status == 401 and "?token=TOKEN" in (error or "") and token_file in (error or ""),
          f"no token: 401 saying how to send it and where it is: {status} {error}")
    status, _ = status_and_error(URL + "/api/state", {"Authorization": "Bearer " + "0" * 48})
    check(status == 401, f"a wrong token: 401 (got {status})")
    status, _ = status_and_error(URL + "/api/state", {"Authorization": "Bearer " + TOKEN})
    check(status == 200, f"the token in the header: 200 (got {status})")
    # Only the page is opened with ?token= (its script moves the token into the header): the
    # API refuses it in the query string, which servers, proxies and histories keep.
    status, error = status_and_error(URL + "/api/state?token=" + TOKEN)
    check(status == 401 and "not as ?token=" in (error or ""),
          f"the token as ?token= on the API: 401 ({status} {error})")
    started = wait_for("the console's start message in the SRP's log", lambda: [
        m["text"] for m in api("/api/srp?max=5000")["messages"] if "web console at" in m["text"]],
        10) or []
    messages = api("/api/srp?max=5000")["messages"]
    check(len(started) == 1 and "API token required" in started[0] and TOKEN not in started[0],
          f"the SRP's message names the URL without the token: {started}")
    check(all(TOKEN not in m["text"] for m in messages), "no SRP message holds the token")


def check_names_render_as_text(driver):
    """A joint name (from a robot's model files) and an SRP message's text that look like HTML
    show as text: the page builds them with textContent, so no element is made and no handler
    runs. The robot is drawn by the page's own createRobot, as for /api/state's robots."""
    hostile = "<img src=x onerror=\"window.__mrrocInjected=1\">"
    shown = driver.execute_script("""
        const name = arguments[0];
        const robot = createRobot({name: "injected", joint_names: [name, "b<b>old</b>"],
                                   units: ["rad", "m"], lower_limits: [0, 0], upper_limits: [1, 1],
                                   cartesian: false});
        const cells = Array.from(robot.element.querySelectorAll(".joints td.joint-name"));
        const result = {texts: cells.map((c) => c.textContent),
                        elements: robot.element.querySelectorAll(".joints img, .joints b").length};
        robot.element.remove();
        robots.delete("injected");
        return result;""", hostile)
    time.sleep(0.2)  # an image's error handler would have run by now
    injected = driver.execute_script("return window.__mrrocInjected === undefined ? null : 1")
    check(shown["texts"] == [hostile, "b<b>old</b>"] and shown["elements"] == 0 and injected is None,
          f"joint names that look like HTML show as text: {shown}, handler ran: {injected}")


def check_token_kept_secret(token, launched, log_dir):
    """No line the launcher printed and no log file under log_dir holds the token."""
    lines = [line for line in launched.lines if token in line]
    check(token != "" and not lines, f"no output line holds the token: {lines[:3]}")
    logs = sorted(os.listdir(log_dir)) if os.path.isdir(log_dir) else []
    holding = [name for name in logs if token in open(os.path.join(log_dir, name),
                                                      errors="replace").read()]
    check("ui.log" in logs and "srp.log" in logs and not holding,
          f"no log file in {log_dir} holds the token ({len(logs)} files: {logs}; holding: {holding})")


def check_token(args, config):
    """A second console on port 8081 with [ui] token_file: the API wants the token; SIGTERM ends
    the console cleanly."""
    token = "0123456789abcdef-console-test"
    token_file = os.path.join(args.artifacts, "ui.token")
    with open(token_file, "w") as f:
        f.write(token + "\n")
    os.chmod(token_file, 0o600)  # a secret: the console refuses one others can read
    text = open(config).read().replace("[ui]\n", f'[ui]\ntoken_file = "{token_file}"\n', 1)
    token_config = os.path.join(args.artifacts, "console-demo-token.toml")
    with open(token_config, "w") as f:
        f.write(text)
    ui = subprocess.Popen([os.path.join(args.bin_dir, "mrroc-ui"), "serve", "--config",
                           token_config, "--port", "8081"])

    def status(headers):
        request = urllib.request.Request("http://127.0.0.1:8081/api/state", headers=headers)
        try:
            with urllib.request.urlopen(request, timeout=5) as response:
                return response.status
        except urllib.error.HTTPError as e:
            return e.code
    try:
        wait_for("the console with a token answers", lambda: status({}) == 401, 10)
        check(status({}) == 401, "no token: 401")
        _, error = status_and_error("http://127.0.0.1:8081/api/state")
        check(token_file in (error or ""), f"the 401 names [ui] token_file: {error}")
        check(status({"Authorization": "Bearer wrong-token-0123456789"}) == 401, "wrong token: 401")
        check(status({"Authorization": "Bearer " + token}) == 200, "right token: 200")
    finally:
        ui.send_signal(15)
        try:
            code = ui.wait(timeout=10)
        except subprocess.TimeoutExpired:
            ui.kill()
            code = None
    check(code == 0, f"SIGTERM ends the console with exit code 0 (got {code})")


def main():
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--source-dir", required=True)
    parser.add_argument("--bin-dir", required=True)
    parser.add_argument("--check-trajectory", required=True)
    parser.add_argument("--artifacts", required=True)
    parser.add_argument("--chromium", default="/usr/bin/chromium")
    parser.add_argument("--chromedriver", default="/usr/bin/chromedriver")
    args = parser.parse_args()

    if os.environ.get("MRROC_IN_NETNS") != "1":
        print("run me inside scripts/netns-run (LCM and the console's port stay private)")
        return 2
    shutil.rmtree(args.artifacts, ignore_errors=True)
    os.makedirs(args.artifacts)
    config = make_config(args.source_dir, args.artifacts)
    global DEMO_POSES, DEMO_VELOCITY_SCALE
    with open(config, "rb") as f:
        ecp_args = tomllib.load(f)["robot"][0]["ecp"]["args"]
    DEMO_POSES, DEMO_VELOCITY_SCALE = ecp_args["poses"], ecp_args["velocity_scale"]
    servo_period_s = 0.002
    bound, ramp, robot = estop_bound_steps(args.source_dir, servo_period_s)
    shots = []

    def screenshot(driver, name):
        path = os.path.join(args.artifacts, f"{len(shots) + 1:02d}-{name}.png")
        driver.save_screenshot(path)
        shots.append(path)
        print(f"screenshot: {path}", flush=True)

    global TOKEN
    # The console's generated token goes to ui-<port>.token in [launch] log_dir.
    log_dir = os.path.join(args.artifacts, "logs")
    token_file = os.path.join(log_dir, "ui-8080.token")
    launched = LaunchedSet(args.bin_dir, config)
    # The launcher starts the console ([ui] web = true) and echoes what it prints; its standard
    # output is the launcher's pipe, not a terminal: it prints where the token is, not the token.
    printed = wait_for("the console prints where its token is",
                       lambda: TOKEN_FILE_LINE.search(launched.output()), 20)
    if printed is None:
        launched.process.terminate()
        return 1
    check(printed.group(1) == token_file, f"the printed token file is {token_file}: {printed.group(1)}")
    check(URL_WITHOUT_TOKEN.search(launched.output()) is not None,
          "the console prints its URL without the token")
    TOKEN = open(token_file).read().strip() if os.path.exists(token_file) else ""
    check(re.fullmatch(r"[0-9a-f]{48}", TOKEN) is not None, "the token file holds 48 hex digits")
    first_token = TOKEN
    wait_for("the console answers", lambda: api("/api/state"), 20)
    state = wait_for("MP IDLE and robot_state_t from the EDP",
                     lambda: (lambda s: s if s["mp"]["state"] == "IDLE" and s["robots"][0]["state"]
                              else None)(api("/api/state")), 30)
    if state is None:
        launched.process.terminate()
        return 1

    check_generated_token(token_file)
    check_token(args, config)

    profile = tempfile.mkdtemp(prefix="mrroc-chromium-")
    options = webdriver.ChromeOptions()
    options.binary_location = args.chromium
    for flag in ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
                 "--no-first-run", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync", f"--user-data-dir={profile}",
                 "--window-size=1500,1300",
                 # WebGL for the 3D view, rendered on the CPU (SwiftShader): no GPU here.
                 "--enable-unsafe-swiftshader", "--use-angle=swiftshader"]:
        options.add_argument(flag)
    driver = webdriver.Chrome(service=Service(args.chromedriver), options=options)
    try:
        driver.get(URL + "/?token=" + TOKEN)
        wait_for("the page shows the MP IDLE", lambda: mp_state(driver) == "IDLE", 10)
        wait_for("the page shows the process table", lambda: len(process_names(driver)) >= 5, 10)
        names = process_names(driver)
        check(all(n in names for n in ["srp", "edp/irb6", "ecp/irb6", "mp", "ui"]),
              f"process table lists srp, edp/irb6, ecp/irb6, mp, ui: {names}")
        check(driver.find_element(By.ID, "estop").is_displayed(), "Emergency stop is visible")
        wait_for("the message log shows the console's start from the history",
                 lambda: "web console at" in driver.find_element(By.ID, "log").text, 10)
        # The EDP's start message came before the console subscribed: only the SRP's history has it.
        check("ready: plugin" in driver.find_element(By.ID, "log").text,
              "the log shows the EDP's start message from the SRP's history")
        check("token" not in driver.current_url,
              f"the page took the token out of the address bar: {driver.current_url}")
        view_model = check_view_loaded(driver, args.source_dir)
        check_names_render_as_text(driver)
        screenshot(driver, "idle")
        check_hostile_requests()
        # The command line: STATUS answers, RESUME while IDLE is refused (exit 1).
        cli = [os.path.join(args.bin_dir, "mrroc-ui")]
        out = subprocess.run(cli + ["status", "--config", config], capture_output=True, text=True)
        check(out.returncode == 0 and "IDLE" in out.stdout, f"mrroc-ui status: {out.stdout.strip()}")
        out = subprocess.run(cli + ["resume", "--config", config], capture_output=True, text=True)
        check(out.returncode == 1 and "REFUSED" in out.stdout,
              f"mrroc-ui resume while IDLE: exit {out.returncode}: {out.stdout.strip()}")

        # --- Start: progress and finish ---------------------------------------------------------
        q0 = joint_cells(driver, "q")
        click(driver, "cmd-start")
        started = time.monotonic()
        wait_for("MP RUNNING shown", lambda: mp_state(driver) == "RUNNING", 5)
        if check(view_model is not None, "the 3D view is there to watch"):
            watch_view(driver, *view_model, 3.0)
            driver.find_element(By.ID, "view-panel").screenshot(
                os.path.join(args.artifacts, "view-running.png"))
        wait_for("the joints change on the page",
                 lambda: any(a is not None and b is not None and abs(a - b) > 0.05
                             for a, b in zip(joint_cells(driver, "q"), q0)), 15)
        time.sleep(1.0)
        # Jogging is refused while the task runs.
        driver.find_element(By.CSS_SELECTOR, '.robot[data-robot="irb6"] .jog-plus').click()
        refusal = wait_for("jog refusal shown", lambda: (lambda t: t if "refused" in t else None)(
            driver.find_element(By.CSS_SELECTOR, '.robot[data-robot="irb6"] .jog-result').text), 5)
        check(refusal is not None and "RUNNING" in refusal, f"jog while running refused: {refusal}")
        screenshot(driver, "running")
        wait_for("MP FINISHED shown", lambda: mp_state(driver) == "FINISHED", 40, 0.1)
        run_s = time.monotonic() - started
        check(run_s > 5.0, f"the run took {run_s:.1f} s (six poses)")
        time.sleep(1.0)  # a few plot samples at rest
        if view_model is not None:
            rest = driver.execute_script(READ_VIEW)["j"]
            now = api("/api/joints")["robots"][0]
            error = max(abs(a - b) for a, b in zip(rest["q"], now["q"]))
            check(not rest["ghost_visible"] and error <= 1e-4,
                  f"3D view at rest: no ghost, the drawn joints are the robot's ({error:.1e} rad)")
        screenshot(driver, "finished")

        # --- Pause and resume ----------------------------------------------------------------------
        click(driver, "cmd-start")
        wait_for("MP RUNNING again", lambda: mp_state(driver) == "RUNNING", 5)
        wait_for("the robot moves", lambda: max(abs(v) for v in
                                                api("/api/state")["robots"][0]["state"]["dq"]) > 0.1, 10)
        click(driver, "cmd-pause")
        wait_for("PAUSED shown", lambda: mp_state(driver) == "PAUSED", 5)
        time.sleep(1.0)  # the macro-step under way completes, the EDP holds
        first = api("/api/state")["robots"][0]["state"]["servo_step"]
        time.sleep(1.0)
        still = samples_after(first)
        max_dq = max(max(abs(v) for v in s["dq"]) for s in still)
        spread = max(max(s["q"][i] for s in still) - min(s["q"][i] for s in still)
                     for i in range(5))
        check(len(still) >= 30 and max_dq < PAUSE_STILL_DQ,
              f"paused: {len(still)} robot states over 1 s, max |dq| {max_dq:.2e} rad/s "
              f"< {PAUSE_STILL_DQ} rad/s; joints moved at most {spread:.2e} rad")
        check(mp_state(driver) == "PAUSED", "still PAUSED")
        screenshot(driver, "paused")
        click(driver, "cmd-resume")
        wait_for("RUNNING after Resume", lambda: mp_state(driver) == "RUNNING", 5)

        # --- Emergency stop during a motion ---------------------------------------------------------
        # Early in a motion (fast and still speeding up) with at least ESTOP_TIME_LEFT_S of it
        # left, so that it still moves when the stop arrives after the page's click on a busy
        # machine (0.3-0.4 s idle, more under load). Resume continued the motion Pause cut short:
        # its rest may be too short, the next pose's motion is not.
        speeds = []

        def time_left(state):
            """Seconds the motion under way still takes at least, to the configured pose it
            heads for (a joint move runs along the straight line in joint space: the pose whose
            direction from q is dq's, cosine > 0.99), each joint at the task's velocity scale;
            0 if it heads for none."""
            q, dq = state["q"], state["dq"]
            speed = math.hypot(*dq)
            best, best_cos = None, 0.99
            for pose in DEMO_POSES:
                d = [p - x for p, x in zip(pose, q)]
                norm = math.hypot(*d)
                if speed > 0 and norm > 0:
                    cos = sum(a * b for a, b in zip(d, dq)) / (norm * speed)
                    if cos > best_cos:
                        best, best_cos = pose, cos
            return 0.0 if best is None else max(
                abs(p - x) / (DEMO_VELOCITY_SCALE * v_max)
                for p, x, v_max in zip(best, q, robot["max_joint_velocity"]))

        def speeding_up():
            state = api("/api/state")["robots"][0]["state"]
            speeds.append(max(abs(v) for v in state["dq"]))
            return state if speeds[-1] > 0.3 and len(speeds) >= 3 and \
                speeds[-3] < speeds[-2] < speeds[-1] and time_left(state) >= ESTOP_TIME_LEFT_S \
                else None
        moving = wait_for("the robot moves fast (max |dq| > 0.3 rad/s), speeds up and has "
                          f"{ESTOP_TIME_LEFT_S} s of its motion left", speeding_up, 20, 0.02)
        click(driver, "estop")
        text = wait_for("the estop's answer shown",
                        lambda: (lambda t: t if "servo step" in t else None)(
                            driver.find_element(By.ID, "command-result").text), 5)
        press_step = int(re.search(r"servo step (\d+)", text or "servo step 0").group(1))
        wait_for("the estop flag shown", lambda: "on" in driver.find_element(
            By.CSS_SELECTOR, '.robot[data-robot="irb6"] .flag[data-flag="estop"]').get_attribute("class"), 5)
        # The robot confirmed its stop from its state: no red "NOT CONFIRMED" banner.
        check(not driver.find_element(By.ID, "estop-banner").is_displayed(),
              "no 'NOT CONFIRMED' banner after a stop the robot confirmed: "
              + driver.find_element(By.ID, "estop-banner").text)
        time.sleep(1.5)
        after = samples_after(press_step - 20)
        at_press = [s for s in after if s["step"] <= press_step]
        speed_at_press = max(abs(v) for v in (at_press[-1] if at_press else after[0])["dq"])
        standstill = None
        for i, s in enumerate(after):
            if s["step"] > press_step and all(
                    max(abs(v) for v in t["dq"]) < STANDSTILL_DQ for t in after[i:]):
                standstill = s
                break
        check(speed_at_press > STANDSTILL_DQ,
              f"the robot was moving when the stop was sent (max |dq| {speed_at_press:.3f} rad/s)")
        if check(standstill is not None, "standstill after the emergency stop"):
            steps = standstill["step"] - press_step
            print(f"emergency stop: pressed at servo step {press_step} with max |dq| "
                  f"{speed_at_press:.3f} rad/s (at {moving and max(abs(v) for v in moving['dq']):.3f} "
                  f"rad/s at step {moving and moving['servo_step']}, seen by the test with at least "
                  f"{moving and time_left(moving):.2f} s of the motion left); every |dq| < {STANDSTILL_DQ} rad/s from step "
                  f"{standstill['step']}: {steps} servo steps ({steps * servo_period_s * 1e3:.0f} ms)",
                  flush=True)
            print(f"bound: slowest ramp max_i(v_max/a_max)/T = {ramp} steps "
                  f"(v_max {robot['max_joint_velocity']} rad/s, a_max "
                  f"{robot['max_joint_acceleration']} rad/s^2, T {servo_period_s * 1e3:.0f} ms) "
                  f"+ 10 (state period) + 25 (delivery, settling) = {bound} steps", flush=True)
            at = at_press[-1]["dq"] if at_press else after[0]["dq"]
            actual = math.ceil(max(abs(v) / a for v, a in zip(at, robot["max_joint_acceleration"]))
                               / servo_period_s)
            print(f"(from the velocities at the press the ramp alone takes {actual} steps)",
                  flush=True)
            check(0 < steps <= bound, f"standstill within {steps} servo steps <= bound {bound}")
        screenshot(driver, "emergency-stop")
        check_hostile_estop()

        click(driver, "release")
        wait_for("the estop flag cleared", lambda: "on" not in driver.find_element(
            By.CSS_SELECTOR, '.robot[data-robot="irb6"] .flag[data-flag="estop"]').get_attribute("class"), 5)
        wait_for("the task is not running (the emergency stop ended the run)",
                 lambda: mp_state(driver) in ("FAILED", "FINISHED", "IDLE"), 15)
        screenshot(driver, "released")

        # --- Jog and teach-in -------------------------------------------------------------------------
        robot_element = driver.find_element(By.CSS_SELECTOR, '.robot[data-robot="irb6"]')
        step_input = robot_element.find_element(By.CSS_SELECTOR, ".jog-step")
        step_input.clear()
        step_input.send_keys("0")
        robot_element.find_elements(By.CSS_SELECTOR, ".jog-plus")[0].click()
        bad = wait_for("bad jog step refused", lambda: (lambda t: t if "outside" in t else None)(
            robot_element.find_element(By.CSS_SELECTOR, ".jog-result").text), 5)
        check(bad is not None and "0 rad" in bad, f"jog step 0 refused: {bad}")
        step_input.clear()
        step_input.send_keys("0.1")
        before = api("/api/state")["robots"][0]["state"]["q"]
        robot_element.find_elements(By.CSS_SELECTOR, ".jog-plus")[0].click()
        result = wait_for("jog result shown", lambda: (lambda t: t if "moved" in t or "refused" in t else None)(
            robot_element.find_element(By.CSS_SELECTOR, ".jog-result").text), 10)
        check(result is not None and "moved" in result, f"jog axis 0 by +0.1 rad: {result}")
        time.sleep(0.5)
        q_after = api("/api/state")["robots"][0]["state"]["q"]
        check(abs(q_after[0] - before[0] - 0.1) < 0.01 and
              all(abs(q_after[i] - before[i]) < 0.01 for i in range(1, 5)),
              f"axis 0 moved {q_after[0] - before[0]:+.4f} rad, the others stayed")
        teach = robot_element.find_element(By.CSS_SELECTOR, ".teach")
        teach.click()
        wait_for("pose 1 recorded", lambda: "pose 1" in robot_element.find_element(
            By.CSS_SELECTOR, ".jog-result").text, 5)
        # Axis 2 towards the middle of its range: where the emergency stop left the arm depends on
        # the machine's speed, and near a limit a step away from the middle is refused (rightly).
        robot = api("/api/state")["robots"][0]
        middle = 0.5 * (robot["lower_limits"][2] + robot["upper_limits"][2])
        towards = ".jog-plus" if robot["state"]["q"][2] < middle else ".jog-minus"
        robot_element.find_elements(By.CSS_SELECTOR, towards)[2].click()
        second = wait_for("second jog", lambda: (lambda t: t if "axis 2" in t and "moved" in t else None)(
            robot_element.find_element(By.CSS_SELECTOR, ".jog-result").text), 10)
        check(second is not None, f"jog axis 2 by 0.1 rad towards the middle of its range: {second}")
        teach.click()
        wait_for("pose 2 recorded", lambda: "pose 2" in robot_element.find_element(
            By.CSS_SELECTOR, ".jog-result").text, 5)
        trajectory = os.path.join(args.artifacts, "taught", "irb6.traj")
        parsed = subprocess.run([args.check_trajectory, trajectory], capture_output=True, text=True)
        print(f"{trajectory}:\n{open(trajectory).read() if os.path.exists(trajectory) else '(none)'}"
              f"parser: {parsed.stdout}{parsed.stderr}", flush=True)
        check(parsed.returncode == 0 and "representation=JOINT axes=5 robot=irb6 poses=2" in parsed.stdout,
              "the taught file parses with the library's trajectory parser: 2 JOINT poses of irb6")
        # The severity filter.
        Select(driver.find_element(By.ID, "log-severity")).select_by_visible_text("WARNING")
        time.sleep(0.3)
        # Read in one go: the log is rendered again whenever a message arrives.
        shown = driver.execute_script(
            "return Array.from(document.querySelectorAll('#log .msg .sev')).map(e => e.textContent)")
        check(len(shown) > 0 and all(sev in ("warning", "error", "fatal") for sev in shown),
              f"severity filter WARNING shows {len(shown)} messages, all warnings or errors: "
              f"{sorted(set(shown))}")
        screenshot(driver, "jog-teach")
        Select(driver.find_element(By.ID, "log-severity")).select_by_visible_text("INFO")

        # --- After the emergency stop the task runs again; then Terminate --------------------------
        click(driver, "cmd-start")
        wait_for("MP RUNNING after the emergency stop", lambda: mp_state(driver) == "RUNNING", 5)
        wait_for("MP FINISHED again", lambda: mp_state(driver) == "FINISHED", 40, 0.1)
        runs = api("/api/state")["mp"]["runs"]
        check(runs == 3, f"the MP counted {runs} runs (3 starts)")
        # --- Terminate -------------------------------------------------------------------------------
        click(driver, "cmd-terminate")
        try:
            code = launched.process.wait(timeout=30)
        except subprocess.TimeoutExpired:
            code = None
        check(code == 0, f"the set ended after Terminate (launcher exit code {code})")
        check(not os.path.exists(token_file), f"the console removed {token_file} at its end")
        check_token_kept_secret(first_token, launched, log_dir)
        time.sleep(1.0)
        screenshot(driver, "terminated")
        check("no connection" in driver.find_element(By.ID, "connection").text,
              "the page shows the console gone")

        # --- Without a launcher: the table comes from the processes' status messages --------------
        by_hand = [subprocess.Popen([os.path.join(args.bin_dir, exe)] + extra + ["--config", config])
                   for exe, extra in [("mrroc-srp", []), ("mrroc-edp", ["--robot", "irb6"]),
                                      ("mrroc-ui", ["serve"])]]
        try:
            # A new console, a new token: read from its file this time.
            fresh = wait_for("the console started by hand writes its token file", lambda: (
                lambda t: t if len(t) == 48 and t != TOKEN else None)(
                open(token_file).read().strip() if os.path.exists(token_file) else ""), 15)
            TOKEN = fresh or ""
            wait_for("the console started by hand answers", lambda: api("/api/state"), 15)
            driver.get(URL + "/?token=" + TOKEN)
            rows = wait_for("srp, edp/irb6 and ui in the table without a launcher", lambda: (
                lambda names: names if all(n in names for n in ["srp", "edp/irb6", "ui"]) else None)(
                process_names(driver)), 10)
            source = driver.find_element(By.ID, "processes-source").text
            check(rows is not None and "status messages" in source,
                  f"without a launcher the table lists {rows} ({source})")
            check(api("/api/state")["launch"] is None, "no launcher table in /api/state")
            wait_for("NO MP shown", lambda: mp_state(driver) == "NO MP", 5)
            wait_for("the page says that no MP answers",
                     lambda: "no MP answers" in driver.find_element(By.ID, "mp-text").text, 5)
            screenshot(driver, "no-launcher")
        finally:
            for p in reversed(by_hand):
                p.send_signal(15)
                try:
                    p.wait(timeout=10)
                except subprocess.TimeoutExpired:
                    p.kill()
            codes = [p.returncode for p in by_hand]
            check(codes == [0, 0, 0], f"SIGTERM ended srp, edp, ui started by hand: {codes}")
            check(not os.path.exists(token_file), f"the console removed {token_file} at its end")
    finally:
        driver.quit()
        shutil.rmtree(profile, ignore_errors=True)
        if launched.process.poll() is None:
            launched.process.terminate()
            launched.process.wait(timeout=20)
    out = subprocess.run([os.path.join(args.bin_dir, "mrroc-ui"), "status", "--config", config,
                          "--timeout", "1"], capture_output=True, text=True)
    check(out.returncode == 3 and "no MP answers" in out.stderr,
          f"mrroc-ui status after the end: exit {out.returncode}: {out.stderr.strip()}")
    left = subprocess.run(["pgrep", "-a", "-f", "mrroc-"], capture_output=True, text=True).stdout
    check(left.strip() == "", f"no mrroc process left behind{': ' + left if left.strip() else ''}")
    print("screenshots:\n" + "\n".join(shots))
    if failures:
        print(f"{len(failures)} check(s) failed:\n  " + "\n  ".join(failures))
        return 1
    print("all checks passed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
