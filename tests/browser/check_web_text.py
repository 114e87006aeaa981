#!/usr/bin/python3
"""The console's page puts data from the set (robot and joint names, SRP texts, process names)
into the page as text, never as HTML: no script of ui/web/ uses an HTML sink (innerHTML,
outerHTML, insertAdjacentHTML, document.write, createContextualFragment, a DOMParser of
"text/html"; view.js parses the robots' MJCF as XML, which never enters the page). Prints
each use as file:line and exits 1 when there is one."""
import pathlib
import re
import sys

SINKS = re.compile(r"\b(innerHTML|outerHTML|insertAdjacentHTML|document\.write(ln)?|"
                   r"createContextualFragment)\b|[\"']text/html[\"']")


def main():
    web = pathlib.Path(sys.argv[1]) if len(sys.argv) > 1 else \
        pathlib.Path(__file__).resolve().parents[2] / "ui" / "web"
    files = sorted(list(web.glob("*.js")) + list(web.glob("*.html")))
    if not files:
        print(f"no scripts found in {web}")
        return 1
    found = []
    for f in files:
        for n, line in enumerate(f.read_text().splitlines(), 1):
            if SINKS.search(line):
                found.append(f"{f}:{n}: {line.strip()}")
    for line in found:
        print(line)
    print(f"{len(files)} files of {web}: {len(found)} HTML sink(s) "
          "(build elements with createElement and set textContent instead)")
    return 1 if found else 0


if __name__ == "__main__":
    sys.exit(main())
