#!/usr/bin/env python3
"""Keeps the lists in the docs equal to the build: docs/getting-started.md's package profiles
against scripts/install-deps, its list of binaries against what CMake installs (every one also
named in README.md), and its CMake options against the option()s of CMakeLists.txt.

Usage: check_docs.py SOURCE_DIR      (exit 1 and one line per difference)
       check_docs.py --self-test     (plants differences in a copy and expects each reported)
"""
import pathlib
import re
import shutil
import subprocess
import sys
import tempfile

GUIDE = "docs/getting-started.md"


def between(text, start, end, what):
    i = text.find(start)
    j = text.find(end, i + len(start)) if i >= 0 else -1
    if i < 0 or j < 0:
        raise LookupError(f"{GUIDE}: no {what} between '{start}' and '{end}'")
    return text[i + len(start):j]


def ticked(text):
    return set(re.findall(r"`([^`\s]+)`", text))


def packages_column(table):
    """The ticked names of the second column of a Markdown table's rows."""
    names = set()
    for line in table.splitlines():
        cells = line.split("|")
        if len(cells) > 3 and not set(cells[2].strip()) <= set("-"):
            names |= ticked(cells[2])
    return names


def script_packages(root, profile):
    out = subprocess.run(["sh", str(root / "scripts/install-deps"), "--list", profile],
                         check=True, capture_output=True, text=True).stdout
    return set(out.split())


def installed_binaries(root):
    names = set()
    for cmake in root.rglob("CMakeLists.txt"):
        rel = cmake.relative_to(root).parts
        if rel[0] in ("tests", "build") or rel[0].startswith("build-"):
            continue
        text = cmake.read_text()
        names |= set(re.findall(r"install\(TARGETS\s+(mrroc-[\w-]+)", text))
        names |= set(re.findall(r"install\(PROGRAMS\s+\S*/(mrroc-[\w-]+)", text))
    return names


def differences(root):
    root = pathlib.Path(root)
    guide = (root / GUIDE).read_text()
    found = []

    demo_doc = packages_column(between(guide, "<!-- packages: demo -->", "<!-- packages: test -->",
                              "demo package list"))
    test_doc = packages_column(between(guide, "<!-- packages: test -->", "<!-- /packages -->",
                              "test package list"))
    demo = script_packages(root, "demo")
    test_only = script_packages(root, "test") - demo
    for name, doc, script in (("demo", demo_doc, demo), ("test", test_doc, test_only)):
        for p in sorted(script - doc):
            found.append(f"{GUIDE}: package '{p}' of profile '{name}' (scripts/install-deps) is not listed")
        for p in sorted(doc - script):
            found.append(f"{GUIDE}: package '{p}' is listed for profile '{name}' but scripts/install-deps does not install it there")

    bins_doc = ticked(between(guide, "<!-- binaries -->", "<!-- /binaries -->", "binary list"))
    bins = installed_binaries(root)
    for b in sorted(bins - bins_doc):
        found.append(f"{GUIDE}: installed binary '{b}' is not listed")
    for b in sorted(bins_doc - bins):
        found.append(f"{GUIDE}: binary '{b}' is listed but nothing installs it")
    readme = (root / "README.md").read_text()
    for b in sorted(bins):
        if b not in readme:
            found.append(f"README.md: installed binary '{b}' is not named")

    top = (root / "CMakeLists.txt").read_text()
    options = set(re.findall(r"^\s*option\((MRROC_\w+)", top, re.M))
    options |= set(re.findall(r"^\s*set\((MRROC_\w+)\s.*\bCACHE\b", top, re.M))
    para = between(guide, "- CMake options", "\n\n", "CMake options paragraph")
    options_doc = set(re.findall(r"`(MRROC_\w+)` \(", para))  # a name, then its default
    for o in sorted(options - options_doc):
        found.append(f"{GUIDE}: CMake option '{o}' is not described")
    for o in sorted(options_doc - options):
        found.append(f"{GUIDE}: CMake option '{o}' is described but CMakeLists.txt has no such option()")
    return found


def self_test(root):
    with tempfile.TemporaryDirectory() as tmp:
        copy = pathlib.Path(tmp)
        cmakes = [str(c.relative_to(root)) for c in root.rglob("CMakeLists.txt")
                  if c.relative_to(root).parts[0] not in ("tests", "build")
                  and not c.relative_to(root).parts[0].startswith("build-")]
        for rel in ["scripts/install-deps", GUIDE, "README.md"] + cmakes:
            (copy / rel).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy(root / rel, copy / rel)
        clean = differences(copy)
        if clean:
            print("self-test: the copy already differs:\n  " + "\n  ".join(clean))
            return 1
        g = copy / GUIDE
        g.write_text(g.read_text().replace("`libfmt-dev`", "`libfmt-devel`", 1))
        c = copy / "CMakeLists.txt"
        c.write_text(c.read_text() + '\noption(MRROC_PLANTED "planted" OFF)\n')
        (copy / "planted").mkdir()
        (copy / "planted/CMakeLists.txt").write_text("install(TARGETS mrroc-planted RUNTIME DESTINATION bin)\n")
        got = "\n".join(differences(copy))
        expected = ["package 'libfmt-dev' of profile 'demo'", "package 'libfmt-devel' is listed",
                    "CMake option 'MRROC_PLANTED' is not described",
                    "installed binary 'mrroc-planted' is not listed",
                    "README.md: installed binary 'mrroc-planted' is not named"]
        missing = [e for e in expected if e not in got]
        if missing:
            print("self-test: not reported: " + "; ".join(missing) + "\ngot:\n" + got)
            return 1
    print("self-test: every planted difference reported")
    return 0


def main():
    if len(sys.argv) == 2 and sys.argv[1] == "--self-test":
        return self_test(pathlib.Path(__file__).resolve().parents[2])
    if len(sys.argv) != 2:
        print(__doc__)
        return 2
    try:
        found = differences(sys.argv[1])
    except LookupError as e:
        print(e)
        return 1
    for line in found:
        print(line)
    if not found:
        print("docs lists match scripts/install-deps, the installed binaries and the CMake options")
    return 1 if found else 0


if __name__ == "__main__":
    sys.exit(main())
