#!/usr/bin/python3
"""Teach-in through the web console's API, played back by the stock ECP task, on a real set.

Starts a set (SRP, EDP with MuJoCo, ECP running `play_trajectory`, MP waiting for the operator,
the console) with mrroc-launch inside scripts/netns-run, then through the console's JSON API
(as its buttons do): Synchronise; jog and Record pose twice; jog away; Start. The ECP reads the
file the console wrote and plays it back. Checked from the EDP's robot states (the console's
samples, every 20 ms) and the launcher's output:
  - the robot rests at the first recorded pose and ends at the second (2e-3 rad), and rests
    nowhere else on the way (no standstill);
  - no joint faster than velocity_scale of its limit (+10 %), no acceleration above its limit;
  - no EDP warning about a late macro-step; the run FINISHED; Terminate ends the set with exit 0.
Also: Start before anything was recorded fails the run with the file named, and the set goes on.
"""
import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import threading
import time
import tomllib
import urllib.error
import urllib.request

URL = "http://127.0.0.1:8080"
TOKEN = ""
VELOCITY_SCALE = 0.5
REST_DQ = 2e-3  # rad/s: every |dq| below this is at rest
failures = []


def check(condition, what):
    print(("ok:   " if condition else "FAIL: ") + what, flush=True)
    if not condition:
        failures.append(what)
    return condition


def api(path, body=None, timeout=10):
    request = urllib.request.Request(URL + path)
    request.add_header("Authorization", "Bearer " + TOKEN)
    if body is not None:
        request.data = json.dumps(body).encode()
        request.add_header("X-Mrroc-Request", "1")
        request.add_header("Content-Type", "application/json")
    try:
        with urllib.request.urlopen(request, timeout=timeout) as response:
            return json.load(response)
    except urllib.error.HTTPError as e:
        return json.load(e)


def wait_for(what, predicate, timeout_s, period_s=0.05):
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        try:
            value = predicate()
            if value:
                return value
        except (OSError, ValueError, KeyError, TypeError, IndexError):
            pass  # the console may not answer yet
        time.sleep(period_s)
    check(False, f"{what} within {timeout_s} s")
    return None


def write_config(folder, source_dir):
    path = os.path.join(folder, "teach-playback.toml")
    with open(path, "w") as f:
        f.write(f'''[system]
name = "teach-playback"
lcm_url = "udpm://239.255.76.67:7667?ttl=0"
ready_timeout_s = 10

[mp]
task = "start_and_wait"
start = "operator"

[ui]
web = true
bind = "127.0.0.1"
port = 8080
teach_dir = "taught"

[[robot]]
name = "irb6"
model = "{os.path.join(source_dir, "robots", "irb6")}"

[robot.edp]
plugin = "mujoco"
servo_period_ms = 2.0

[robot.ecp]
task = "play_trajectory"

[robot.ecp.args]
file = "taught/irb6.traj"
velocity_scale = {VELOCITY_SCALE}
acceleration_scale = {VELOCITY_SCALE}
''')
    os.makedirs(os.path.join(folder, "taught"), exist_ok=True)
    return path


def mp_state():
    return api("/api/state")["mp"]


def run_once():
    """Start; waits for the run to end; returns the MP's status after it."""
    runs = mp_state()["runs"]
    answer = api("/api/command/start", {})
    check(answer.get("accepted") is True, f"Start accepted: {answer}")
    return wait_for("the run ends", lambda: (lambda m: m if m["runs"] > runs and
                                             m["state"] not in ("RUNNING", "STOPPING") else None)(
        mp_state()), 60, 0.1)


def jog(axis, step, direction):
    answer = api("/api/jog", {"robot": "irb6", "axis": axis, "step_rad": step,
                              "direction": direction})
    check(answer.get("ok") is True, f"jog axis {axis} by {direction * step:+} rad: "
          f"{answer.get('text') or answer.get('error')}")
    return answer.get("q")


def rest_intervals(samples):
    """[(first, last)] index ranges of samples at rest (every |dq| < REST_DQ)."""
    out, start = [], None
    for i, s in enumerate(samples):
        still = max(abs(v) for v in s["dq"]) < REST_DQ
        if still and start is None:
            start = i
        if not still and start is not None:
            out.append((start, i - 1))
            start = None
    if start is not None:
        out.append((start, len(samples) - 1))
    return out


def distance(a, b):
    return max(abs(x - y) for x, y in zip(a, b))


def main():
    global TOKEN
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--source-dir", required=True)
    parser.add_argument("--bin-dir", required=True)
    args = parser.parse_args()
    with open(os.path.join(args.source_dir, "robots", "irb6", "parameters.toml"), "rb") as f:
        robot = tomllib.load(f)["robot"]
    vmax, amax = robot["max_joint_velocity"], robot["max_joint_acceleration"]

    folder = tempfile.mkdtemp(prefix="mrroc-teach-playback-")
    config = write_config(folder, args.source_dir)
    lines = []
    launcher = subprocess.Popen([os.path.join(args.bin_dir, "mrroc-launch"), config],
                                stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                                cwd=folder)

    def read():
        for line in launcher.stdout:
            lines.append(line.rstrip("\n"))
            print("  | " + line.rstrip("\n"), flush=True)

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    try:
        # Its standard output is the launcher's pipe: the console prints where its token is.
        url = re.compile(r"API token in (\S+) \(removed when the console ends\)$")
        token_file = wait_for("the console's token file", lambda: next(
            (m.group(1) for m in map(url.search, list(lines)) if m), None), 30) or ""
        TOKEN = open(token_file).read().strip() if token_file else ""
        state = wait_for("a robot state from the EDP", lambda: api("/api/state")["robots"][0]["state"], 30)
        check(state is not None and not state["synchronised"], "the robot starts not synchronised")
        wait_for("the MP waiting for the operator", lambda: mp_state().get("state") == "IDLE", 30)

        # Start with nothing recorded: the run fails naming the file; the set goes on.
        status = run_once()
        check(status is not None and status["state"] == "FAILED" and
              "taught/irb6.traj: error: no such trajectory file" in status.get("text", ""),
              f"a run without a recorded file fails, naming it: {status}")

        answer = api("/api/synchronise", {"robot": "irb6"}, timeout=60)
        check(answer.get("ok") is True and "synchronised at" in answer.get("text", ""),
              f"Synchronise: {answer.get('text') or answer.get('error')}")
        again = api("/api/synchronise", {"robot": "irb6"})
        check(again.get("text") == "irb6 is already synchronised", f"Synchronise again: {again}")

        jog(0, 0.2, 1)
        jog(0, 0.2, 1)
        first = api("/api/teach", {"robot": "irb6"})
        check(first.get("ok") is True and first.get("points") == 1, f"Record pose 1: {first}")
        jog(2, 0.15, -1)
        jog(3, 0.2, 1)
        second = api("/api/teach", {"robot": "irb6"})
        check(second.get("ok") is True and second.get("points") == 2, f"Record pose 2: {second}")
        jog(0, 0.2, -1)
        jog(0, 0.2, -1)
        jog(0, 0.2, -1)
        # The tool frame along its approach axis, through the same EDP checks.
        before = api("/api/state")["robots"][0]["state"]["q"]
        tool = api("/api/jog", {"robot": "irb6", "space": "tool", "axis": 2, "step": 0.02,
                                "direction": -1})
        check(tool.get("ok") is True and "irb6 tool z moved -0.0200 m" in tool.get("text", "")
              and distance(tool.get("q", before), before) > 1e-3,
              f"tool jog z by -0.02 m: {tool.get('text') or tool.get('error')}")
        sideways = api("/api/jog", {"robot": "irb6", "space": "tool", "axis": 1, "step": 0.02})
        check("tool jog refused: irb6 y by +0.0200 m" in sideways.get("error", ""),
              f"the five-axis arm cannot move its tool sideways: {sideways}")
        start_pose = api("/api/state")["robots"][0]["state"]
        p1, p2 = first["pose"], second["pose"]
        check(distance(start_pose["q"], p2) > 0.3, "the robot was jogged away from the poses")

        mark = start_pose["servo_step"]
        status = run_once()
        check(status is not None and status["state"] in ("IDLE", "FINISHED") and not status.get("error"),
              f"the playback run ended without error: {status}")
        time.sleep(0.3)  # the last states of the run
        samples = api(f"/api/robots/irb6/samples?after={mark}")["samples"]
        check(len(samples) > 50, f"{len(samples)} robot states of the run")
        if samples:
            end = samples[-1]["q"]
            check(distance(end, p2) < 2e-3, f"ends at recorded pose 2 ({distance(end, p2):.2e} rad)")
            rests = rest_intervals(samples)
            moving = [r for r in rests if 0 < r[0] and r[1] < len(samples) - 1]
            at = [samples[r[0]]["q"] for r in moving]
            check(any(distance(q, p1) < 2e-3 for q in at),
                  f"rests at recorded pose 1 on the way ({[round(distance(q, p1), 4) for q in at]})")
            stray = [q for q in at if distance(q, p1) >= 2e-3 and distance(q, p2) >= 2e-3
                     and distance(q, start_pose["q"]) >= 2e-3]
            check(not stray, f"no standstill away from the recorded poses ({len(stray)} found)")
            fastest = [max(abs(s["dq"][j]) for s in samples) for j in range(len(vmax))]
            check(all(v <= VELOCITY_SCALE * vm * 1.1 for v, vm in zip(fastest, vmax)),
                  f"joint speeds {[round(v, 3) for v in fastest]} within {VELOCITY_SCALE} of "
                  f"{vmax} rad/s (+10 %)")
            accelerations = [0.0] * len(amax)
            for a, b in zip(samples, samples[1:]):
                dt = (b["utime"] - a["utime"]) * 1e-6
                if dt <= 0:
                    continue
                for j in range(len(amax)):
                    accelerations[j] = max(accelerations[j], abs(b["dq"][j] - a["dq"][j]) / dt)
            check(all(a <= am for a, am in zip(accelerations, amax)),
                  f"joint accelerations {[round(a, 2) for a in accelerations]} within {amax} rad/s^2")
        output = "\n".join(lines)
        check("no next macro-step" not in output and "standstill" not in output,
              "no late macro-step or standstill reported by the EDP")
        check("trajectory played" in output, "the ECP reported the trajectory played")

        api("/api/command/terminate", {})
        try:
            code = launcher.wait(timeout=30)
        except subprocess.TimeoutExpired:
            code = None
        check(code == 0, f"Terminate ends the set, launcher exit code {code}")
    finally:
        if launcher.poll() is None:
            launcher.terminate()
            try:
                launcher.wait(timeout=15)
            except subprocess.TimeoutExpired:
                launcher.kill()
        reader.join(timeout=5)
        shutil.rmtree(folder, ignore_errors=True)
    if failures:
        print(f"{len(failures)} check(s) failed:\n  " + "\n  ".join(failures))
        return 1
    print("teach-in playback: every check passed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
