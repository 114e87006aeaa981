#!/usr/bin/python3
"""The scene's objects in the web console's 3D view, in headless Chromium (Selenium).

Runs tests/browser/view-objects/set.toml (the conveyor on emulated CiA 402 drives in the cell of
view-objects/scene.toml: a part on the belt, a table with a bar on it, a ball, a can and a
capsule; the console started by mrroc-launch) inside scripts/netns-run and checks:
  - GET /api/objects lists the scene file's objects (name, shape, size, colour, attach) from the
    emulator's scene_objects_t messages;
  - the 3D view (read back with window.mrrocView.objects()) draws as many objects as the file has,
    with its shapes and sizes (read back from the drawn geometry) and colours;
  - free and world-fixed objects are drawn at the emulator's published poses (the view's poses
    and /api/objects compared for the same message number): the bar lies on the table;
  - Start moves the belt: the part, attached to the belt's link, is drawn on the drawn link at
    its pose in the file, travels with it, and stays within PART_TOL of the emulator's pose of
    the part (the two come from different messages: the EDP's robot state and the emulator's);
  - the view keeps its rates (robot states and frames per second, as test_console.py asks);
and leaves a picture of the view: <artifacts>/view-objects.png.
"""
import argparse
import math
import os
import re
import shutil
import sys
import tempfile
import time
import tomllib

from selenium import webdriver
from selenium.webdriver.chrome.service import Service
from selenium.webdriver.common.by import By

sys.dont_write_bytecode = True
import test_console as tc  # noqa: E402 (beside this file: api, check, wait_for, LaunchedSet)

SIZE_TOL = 1e-9     # m: a drawn size vs. the scene file's
POSE_TOL = 1e-9     # m and quaternion elements: a drawn pose vs. the published one
ON_TABLE_TOL = 2e-3  # m: the bar's centre above the table top by its half-height
# The part drawn on the drawn belt vs. the emulator's pose of it while the belt moves: the robot
# state drawn and the object poses served come from different moments; the distance may be the
# belt's top speed (velocity_scale 0.5 of 0.5 m/s in view-objects/set.toml) times the time between
# them, plus PART_TOL.
BELT_SPEED = 0.25   # m/s
PART_TOL = 0.01     # m
MIN_TRAVEL = 0.2    # m: the part's drawn travel while watched
MIN_OBJECT_PIXELS = 1000  # coloured pixels the objects add to the picture
AT_REST_TOL = 2e-3  # m: the part drawn on the belt at rest vs. the emulator's pose of it

READ = ("const v = window.mrrocView; return {o: v.objects(), l: v.linkPoses('conveyor'), "
        "j: v.jointValues('conveyor'), s: v.stats()};")


def quat_close(a, b, tol):
    """Quaternions (w, x, y, z) equal up to the sign."""
    return (max(abs(x - y) for x, y in zip(a, b)) <= tol or
            max(abs(x + y) for x, y in zip(a, b)) <= tol)


def rotate(q, v):
    """v rotated by the unit quaternion q = (w, x, y, z)."""
    w, x, y, z = q
    t = [2 * (y * v[2] - z * v[1]), 2 * (z * v[0] - x * v[2]), 2 * (x * v[1] - y * v[0])]
    return [v[0] + w * t[0] + (y * t[2] - z * t[1]),
            v[1] + w * t[1] + (z * t[0] - x * t[2]),
            v[2] + w * t[2] + (x * t[1] - y * t[0])]


def check_description(objects, scene, where):
    names = [o["name"] for o in objects]
    tc.check(names == [o["name"] for o in scene],
             f"{where}: the scene file's {len(scene)} objects in its order: {names}")
    for o, s in zip(objects, scene):
        size_error = max((abs(a - b) for a, b in zip(o["size"], s["size"])), default=math.inf)
        colour = s.get("rgba", [0.8, 0.3, 0.2, 1.0])
        rgba_error = max(abs(a - b) for a, b in zip(o["rgba"], colour))
        tc.check(o["shape"] == s["type"] and len(o["size"]) == len(s["size"]) and
                 size_error <= SIZE_TOL and rgba_error <= 1e-3 and
                 o["attach"] == s.get("attach", ""),
                 f"{where}: '{o['name']}' is a {o['shape']} of size {o['size']} m (file: "
                 f"{s['type']} {s['size']}), colour {[round(c, 3) for c in o['rgba']]}, attached "
                 f"to '{o['attach']}'")


def matched_reads(driver, tries):
    """Pairs (drawn, served) of the view's objects and GET /api/objects with the same message
    number."""
    pairs = []
    for _ in range(tries):
        before = tc.view(driver, "window.mrrocView.objects()")
        served = tc.api("/api/objects")
        after = tc.view(driver, "window.mrrocView.objects()")
        for drawn in (before, after):
            if drawn["seq"] is not None and drawn["seq"] == served["seq"]:
                pairs.append((drawn, served))
                break
        time.sleep(0.02)
    return pairs


def pose_error(drawn, served):
    dp = max(abs(a - b) for a, b in zip(drawn["position"], served["position"]))
    dq = min(max(abs(a - b) for a, b in zip(drawn["quaternion"], served["quaternion"])),
             max(abs(a + b) for a, b in zip(drawn["quaternion"], served["quaternion"])))
    return max(dp, dq)


def main():
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--source-dir", required=True)
    parser.add_argument("--bin-dir", required=True)
    parser.add_argument("--artifacts", required=True)
    parser.add_argument("--chromium", default="/usr/bin/chromium")
    parser.add_argument("--chromedriver", default="/usr/bin/chromedriver")
    args = parser.parse_args()
    if os.environ.get("MRROC_IN_NETNS") != "1":
        print("run me inside scripts/netns-run (LCM and the console's port stay private)")
        return 2
    shutil.rmtree(args.artifacts, ignore_errors=True)
    os.makedirs(args.artifacts)
    folder = os.path.join(args.source_dir, "tests", "browser", "view-objects")
    with open(os.path.join(folder, "scene.toml"), "rb") as f:
        scene = tomllib.load(f)["scene"]["object"]
    by_name = {s["name"]: s for s in scene}

    launched = tc.LaunchedSet(args.bin_dir, os.path.join(folder, "set.toml"))
    driver = None
    profile = tempfile.mkdtemp(prefix="mrroc-chromium-")
    try:
        # The console's standard output is the launcher's pipe: it prints where its token is.
        printed = tc.wait_for("the console prints where its token is",
                              lambda: tc.TOKEN_FILE_LINE.search(launched.output()), 30)
        if printed is None:
            return 1
        tc.TOKEN = open(printed.group(1)).read().strip()
        served = tc.wait_for("GET /api/objects lists the emulator's objects", lambda: (
            lambda d: d if len(d["objects"]) == len(scene) else None)(tc.api("/api/objects")), 30)
        if served is None:
            return 1
        tc.check(served["scene"] == "view-objects", f"the scene's name: {served['scene']}")
        check_description(served["objects"], scene, "GET /api/objects")
        tc.wait_for("MP IDLE and the conveyor's robot state", lambda: (
            lambda s: s["mp"]["state"] == "IDLE" and s["robots"][0]["state"])(
            tc.api("/api/state")), 30)

        options = webdriver.ChromeOptions()
        options.binary_location = args.chromium
        for flag in ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
                     "--no-first-run", "--disable-background-networking",
                     "--disable-component-update", "--disable-sync",
                     f"--user-data-dir={profile}", "--window-size=1500,1300",
                     "--enable-unsafe-swiftshader", "--use-angle=swiftshader"]:
            options.add_argument(flag)
        driver = webdriver.Chrome(service=Service(args.chromedriver), options=options)
        driver.get(tc.URL + "/?token=" + tc.TOKEN)
        drawn = tc.wait_for("the 3D view draws the scene's objects", lambda: tc.view(
            driver, "window.mrrocView.ready && window.mrrocView.objects().objects.length === "
            f"{len(scene)} && window.mrrocView.objects()"), 30)
        if drawn is None:
            print("3D view: " + driver.find_element(By.ID, "view-note").text, flush=True)
            return 1
        check_description(drawn["objects"], scene, "3D view")
        on = {o["name"]: o["drawn_on"] for o in drawn["objects"]}
        tc.check(on["part"] == "link" and all(v == "emulator" for k, v in on.items()
                                              if k != "part"),
                 f"the part is drawn on the conveyor's belt link, the others at the emulator's "
                 f"poses: {on}")

        # At rest: every object not on a link drawn at the pose of the same message.
        pairs = matched_reads(driver, 40)
        errors = [pose_error(d, s) for drawn_, served_ in pairs
                  for d, s in zip(drawn_["objects"], served_["objects"]) if d["drawn_on"] ==
                  "emulator"]
        tc.check(len(pairs) >= 5 and max(errors, default=math.inf) <= POSE_TOL,
                 f"{len(pairs)} readings of the view with the message number of /api/objects: "
                 f"the free and fixed objects drawn at the published poses within "
                 f"{max(errors, default=math.inf):.1e} <= {POSE_TOL}")
        before = [math.dist(next(o for o in d["objects"] if o["name"] == "part")["position"],
                            next(o for o in s["objects"] if o["name"] == "part")["position"])
                  for d, s in pairs]
        print(f"before Start (the belt not yet synchronised): the part drawn on the belt is "
              f"{max(before, default=math.nan) * 1000:.1f} mm from the emulator's pose of it",
              flush=True)
        bar = next(o for o in drawn["objects"] if o["name"] == "bar")
        table = by_name["table"]
        top = table["pos"][2] + table["size"][2]
        tc.check(abs(bar["position"][2] - top - by_name["bar"]["size"][2]) <= ON_TABLE_TOL,
                 f"the bar is drawn lying on the table: its centre {bar['position'][2]:.4f} m, the "
                 f"table's top {top} m + {by_name['bar']['size'][2]} m")
        pixels = tc.view(driver, "window.mrrocView.visiblePixels()")["coloured"]
        without = tc.view(driver, "window.mrrocView.visiblePixels(false)")["coloured"]
        tc.check(pixels - without >= MIN_OBJECT_PIXELS,
                 f"the objects are visible: {pixels} coloured pixels with them, {without} without "
                 f"(at least {MIN_OBJECT_PIXELS} more)")

        # Start: the belt carries the part.
        reply = tc.api("/api/command/start", {})
        tc.check(reply.get("accepted") is True, f"Start accepted: {reply}")
        tc.wait_for("the belt synchronised and moving at 0.15 m/s", lambda: (
            lambda s: s["synchronised"] and abs(s["dq"][0]) > 0.15)(
            tc.api("/api/state")["robots"][0]["state"]), 20)
        q_start = tc.api("/api/state")["robots"][0]["state"]["q"][0]
        records, compared = [], []
        end = time.monotonic() + 3.0
        while time.monotonic() < end:
            records.append(driver.execute_script(READ))
            served = tc.api("/api/objects")
            compared.append((records[-1], served))
            time.sleep(0.1)
        driver.find_element(By.ID, "view-panel").screenshot(
            os.path.join(args.artifacts, "view-objects.png"))
        part = by_name["part"]
        travel = 0.0
        link_error = 0.0
        emulator_excess = -math.inf  # the largest distance beyond its bound [m]
        worst = ""
        for record, served_ in compared:
            p = next(o for o in record["o"]["objects"] if o["name"] == "part")
            first = next(o for o in records[0]["o"]["objects"] if o["name"] == "part")
            travel = max(travel, math.dist(p["position"], first["position"]))
            belt = record["l"]["belt_link"]  # position, quaternion [x, y, z, w]
            bq = [belt["quaternion"][3]] + belt["quaternion"][:3]
            expected = [a + b for a, b in zip(belt["position"], rotate(bq, part["pos"]))]
            link_error = max(link_error, max(abs(a - b) for a, b in zip(p["position"], expected)))
            s = next(o for o in served_["objects"] if o["name"] == "part")
            apart_s = abs(served_["utime"] - record["j"]["utime"]) / 1e6
            distance = math.dist(p["position"], s["position"])
            if distance - (BELT_SPEED * apart_s + PART_TOL) > emulator_excess:
                emulator_excess = distance - (BELT_SPEED * apart_s + PART_TOL)
                worst = f"{distance * 1000:.1f} mm with {apart_s * 1000:.0f} ms between them"
        q_end = tc.api("/api/state")["robots"][0]["state"]["q"][0]
        tc.check(travel >= MIN_TRAVEL,
                 f"the part drawn on the belt travels {travel:.3f} m >= {MIN_TRAVEL} m in 3 s "
                 f"(the belt from {q_start:.3f} m to {q_end:.3f} m)")
        tc.check(link_error <= POSE_TOL,
                 f"the part drawn at its pose on the drawn belt link within {link_error:.1e} m")
        tc.check(emulator_excess <= 0.0,
                 f"the part drawn within {BELT_SPEED} m/s times the time between the robot state "
                 f"drawn and the emulator's poses served, + {PART_TOL * 1000} mm, of the "
                 f"emulator's pose of it (the closest to its bound: {worst})")
        later = records[len(records) // 3:]
        states = sorted(r["s"]["states_per_s"]["conveyor"] for r in later)
        frames = sorted(r["s"]["frames_per_s"] for r in later)
        load = os.getloadavg()[0]
        cpus = os.cpu_count() or 1
        bound = tc.VIEW_MIN_RATE if load <= tc.VIEW_BUSY_LOAD * cpus else tc.VIEW_MIN_RATE_BUSY
        tc.check(states[len(states) // 2] >= bound,
                 f"3D view with the objects: median {states[len(states) // 2]} robot states "
                 f"drawn per second >= {bound} (load average {load:.1f} on {cpus} CPUs)")
        tc.check(frames[len(frames) // 2] >= tc.VIEW_MIN_FRAMES,
                 f"3D view with the objects: median {frames[len(frames) // 2]} frames per second "
                 f">= {tc.VIEW_MIN_FRAMES} (drawn on the CPU)")

        # At rest after the run: the part drawn on the belt where the emulator has it.
        tc.wait_for("MP FINISHED", lambda: tc.api("/api/state")["mp"]["state"] == "FINISHED", 30)
        time.sleep(0.5)
        pairs = matched_reads(driver, 10)
        rest = [math.dist(next(o for o in d["objects"] if o["name"] == "part")["position"],
                          next(o for o in s["objects"] if o["name"] == "part")["position"])
                for d, s in pairs]
        tc.check(len(pairs) >= 1 and max(rest, default=math.inf) <= AT_REST_TOL,
                 f"at rest after the run the part drawn on the drawn belt is within "
                 f"{max(rest, default=math.inf) * 1000:.2f} mm <= {AT_REST_TOL * 1000} mm of the "
                 f"emulator's pose of it")
        driver.find_element(By.ID, "view-panel").screenshot(
            os.path.join(args.artifacts, "view-objects-finished.png"))
        reply = tc.api("/api/command/terminate", {})
        try:
            code = launched.process.wait(timeout=30)
        except Exception:
            code = None
        tc.check(code == 0, f"the set ended after Terminate (launcher exit code {code})")
    finally:
        if driver is not None:
            driver.quit()
        shutil.rmtree(profile, ignore_errors=True)
        if launched.process.poll() is None:
            launched.process.terminate()
            launched.process.wait(timeout=20)
    if tc.failures:
        print(f"FAILED: {len(tc.failures)} check(s):\n  " + "\n  ".join(tc.failures))
        return 1
    print("all checks passed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
