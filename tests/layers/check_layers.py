#!/usr/bin/env python3
"""Checks that every #include in the library and process folders points down the layers.

The layers are the folders of the libraries (src/CMakeLists.txt, docs/architecture.md "Libraries"):
a file of one area may include the public headers (include/mrroc/<area>/) of the areas listed
for it below, and its own; LCM and MuJoCo headers only where listed. Prints one
`file:line: error: ...` per include that points up or sideways and exits 1 when there is any.

Usage: check_layers.py [SOURCE_DIR]     (default: the tree this script is in)
       check_layers.py --self-test      (checks that a planted upward include is reported)
"""
import os
import re
import sys
import tempfile

# area -> areas whose headers it may include (besides its own).
FOUNDATION = {"core", "config"}
ALLOWED = {
    "core": set(),
    "config": {"core"},
    "msg": {"core"},
    "comm": FOUNDATION | {"msg"},
    "robot": FOUNDATION | {"msg"},
    "kinematics": FOUNDATION | {"msg", "robot"},
    "edp": FOUNDATION | {"msg", "robot", "kinematics"},
    "robots": FOUNDATION | {"msg", "robot", "kinematics", "edp"},
    "vsp": FOUNDATION | {"msg"},
    "ecp": FOUNDATION | {"msg", "comm", "robot", "kinematics", "edp", "vsp"},
    "mp": FOUNDATION | {"msg", "comm", "robot", "kinematics", "edp", "vsp", "ecp"},
    # Private libraries of the EDP's plugins and the emulator.
    "can": FOUNDATION,
    "sim": FOUNDATION | {"robot"},
}
# Sources that may include more than their layer: the clients of an EDP and of a VSP talk over
# the bus (comm), while the headers of their layers (the extension points, and the clients' own
# headers, which hide the link behind a pointer) stay free of it.
SOURCE_EXTRA = {
    "src/edp/client.cpp": {"comm"},
    "src/vsp/client.cpp": {"comm"},
}
LIBRARY_AREAS = set(ALLOWED)
PUBLIC_AREAS = LIBRARY_AREAS - {"robots", "can", "sim"}
# Process folders (one executable each) may include every public library area; the private
# libraries only where named.
PROCESSES = {
    "edp": PUBLIC_AREAS | {"can", "sim"},
    "emu": PUBLIC_AREAS | {"can", "sim"},
    "ecp": PUBLIC_AREAS,
    "mp": PUBLIC_AREAS,
    "vsp": PUBLIC_AREAS,
    "ui": PUBLIC_AREAS,
    "srp": PUBLIC_AREAS,
    "launch": PUBLIC_AREAS,
    # mrroc-can, the commissioning tool, speaks CANopen itself.
    "tools": PUBLIC_AREAS | {"can"},
}
# Third-party headers bound to a layer: prefix -> areas (library or "process:<name>") allowed.
EXTERNAL = {
    "lcm/": {"comm", "process:*"},
    "mrroc_lcm/": {"comm", "process:*"},
    "mujoco/": {"sim", "process:edp", "process:emu"},
    "httplib": {"process:ui"},
}
INCLUDE = re.compile(r'^\s*#\s*include\s*[<"]([^>"]+)[>"]')


def area_of(rel):
    """('library', area) or ('process', name) for a path relative to the tree, else None."""
    parts = rel.split("/")
    if parts[0] == "include" and len(parts) > 3 and parts[1] == "mrroc":
        return ("library", parts[2])
    if parts[0] == "src" and len(parts) > 2:
        return ("library", parts[1])
    if parts[0] == "robots" and len(parts) > 2:
        return ("library", "robots")
    if parts[0] in PROCESSES and len(parts) > 1:
        return ("process", parts[0])
    return None


def header_area(header):
    if header.startswith("mrroc/"):
        parts = header.split("/")
        if len(parts) > 2:
            return parts[1]
    return None


def check(root):
    errors = []
    folders = ["include", "src", "robots"] + sorted(PROCESSES)
    for top in folders:
        for dirpath, dirnames, filenames in os.walk(os.path.join(root, top)):
            dirnames.sort()
            for name in sorted(filenames):
                if not name.endswith((".hpp", ".cpp", ".h")):
                    continue
                path = os.path.join(dirpath, name)
                rel = os.path.relpath(path, root)
                kind_area = area_of(rel)
                if kind_area is None:
                    continue
                kind, area = kind_area
                if kind == "library" and area not in ALLOWED:
                    errors.append(f"{rel}:1: error: folder of no known layer ({area}); "
                                  "add it to tests/layers/check_layers.py and docs/architecture.md")
                    continue
                allowed = ALLOWED[area] if kind == "library" else PROCESSES[area]
                allowed = allowed | SOURCE_EXTRA.get(rel.replace(os.sep, "/"), set())
                who = area if kind == "library" else f"process:{area}"
                with open(path, encoding="utf-8", errors="replace") as f:
                    for number, line in enumerate(f, 1):
                        m = INCLUDE.match(line)
                        if not m:
                            continue
                        header = m.group(1)
                        target = header_area(header)
                        if target is not None:
                            if kind == "library" and target == area:
                                continue
                            if target not in allowed:
                                what = ("a process" if kind == "process" else "layer")
                                errors.append(
                                    f"{rel}:{number}: error: {what} '{area}' includes "
                                    f"<{header}> of '{target}', which it may not (it may include: "
                                    f"{', '.join(sorted(allowed)) or 'nothing of mrroc'})")
                            continue
                        for prefix, areas in EXTERNAL.items():
                            if header.startswith(prefix):
                                ok = who in areas or (kind == "process" and "process:*" in areas)
                                if not ok:
                                    errors.append(
                                        f"{rel}:{number}: error: '{area}' includes <{header}>, "
                                        f"which only {', '.join(sorted(areas))} may include")
    return errors


def self_test():
    with tempfile.TemporaryDirectory() as tmp:
        for folder in ("include/mrroc/core", "include/mrroc/comm", "include/mrroc/edp", "src/edp"):
            os.makedirs(os.path.join(tmp, folder))
        with open(os.path.join(tmp, "include/mrroc/comm/bus.hpp"), "w") as f:
            f.write('#include "mrroc/core/error.hpp"\n#include <lcm/lcm-cpp.hpp>\n')
        with open(os.path.join(tmp, "include/mrroc/core/error.hpp"), "w") as f:
            f.write("#pragma once\n")
        # The EDP client's source may include comm (SOURCE_EXTRA).
        with open(os.path.join(tmp, "src/edp/client.cpp"), "w") as f:
            f.write('#include "mrroc/edp/client.hpp"\n#include "mrroc/comm/bus.hpp"\n')
        with open(os.path.join(tmp, "include/mrroc/edp/client.hpp"), "w") as f:
            f.write("#pragma once\n")
        found = check(tmp)
        if found:
            print("self-test: a tree that points down was reported:", found)
            return 1
        with open(os.path.join(tmp, "include/mrroc/core/error.hpp"), "a") as f:
            f.write('#include "mrroc/comm/bus.hpp"\n#include <mujoco/mujoco.h>\n')
        # ... but not its header, nor another source of its layer.
        with open(os.path.join(tmp, "include/mrroc/edp/client.hpp"), "a") as f:
            f.write('#include "mrroc/comm/bus.hpp"\n')
        with open(os.path.join(tmp, "src/edp/hardware_registry.cpp"), "w") as f:
            f.write('#include "mrroc/comm/bus.hpp"\n')
        found = check(tmp)
        if (len(found) != 4 or "of 'comm'" not in found[0] or "mujoco" not in found[1]
                or not found[2].startswith("include/mrroc/edp/client.hpp:2:")
                or not found[3].startswith("src/edp/hardware_registry.cpp:1:")):
            print("self-test: the planted upward includes were not all reported:", found)
            return 1
        print("self-test: passed (" + "; ".join(found) + ")")
    return 0


def main(argv):
    if len(argv) > 1 and argv[1] in ("-h", "--help"):
        print(__doc__.strip())
        return 0
    if len(argv) > 1 and argv[1] == "--self-test":
        return self_test()
    root = argv[1] if len(argv) > 1 else os.path.join(os.path.dirname(os.path.abspath(__file__)),
                                                      "..", "..")
    errors = check(os.path.abspath(root))
    for e in errors:
        print(e)
    if errors:
        print(f"layers: {len(errors)} include(s) point up or sideways (docs/architecture.md, Libraries)")
        return 1
    print("layers: every include points down")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
