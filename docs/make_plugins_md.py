#!/usr/bin/env python3
"""docs/plugins.md from `lode plugins --json`: the catalogue of shipped plugins with their
ports and parameters. The plugins_md_test regenerates it and fails when the committed file
differs, so it cannot go stale.

usage: lode plugins --json | docs/make_plugins_md.py > docs/plugins.md
"""
import json
import sys


def cell(text):
    return str(text).replace("|", "\\|").replace("\n", " ")


def table(header, rows):
    """A markdown table (nothing when there are no rows), followed by a blank line."""
    if not rows:
        return []
    return (["| " + " | ".join(header) + " |", "|" + "---|" * len(header)] +
            ["| " + " | ".join(row) + " |" for row in rows] + [""])


def main():
    plugins = sorted(json.load(sys.stdin), key=lambda p: p["name"])
    out = ["# Plugins", "",
           "Every plugin shipped with lodestone, with its ports and parameters. Generated from",
           "`lode plugins --json` by `docs/make_plugins_md.py`; `lode plugins NAME` shows one on",
           "the command line. Each plugin's own README (`plugins/<kind>/<name>/README.md`) has the",
           "equations, units and measured figures. Models (plant, sensor) have no ports: their",
           "inputs and outputs are listed in their READMEs.", ""]
    kinds = {}
    for p in plugins:
        kinds.setdefault(p["name"].split(".")[0], []).append(p)
    out.append("| plugin | summary |")
    out.append("|---|---|")
    for p in plugins:
        out.append(f"| [`{p['name']}`](#{p['name'].replace('.', '')}) | {cell(p['summary'])} |")
    out.append("")
    for p in plugins:
        out.append(f"## {p['name']}")
        out.append("")
        out.append(f"{cell(p['summary'])} (version {p['version']}, {p['kind']})")
        out.append("")
        out += table(["port", "direction", "what", "present"],
                     [[f"`{port['name']}`", port["direction"], cell(port["description"]),
                       "always" if port.get("condition") is None else cell(port["condition"])]
                      for port in p["ports"]])
        out += table(["parameter", "type", "default", "what"],
                     [[f"`{q['name']}`", cell(q["type"]),
                       "(required)" if q["default"] is None else f"`{cell(q['default'])}`", cell(q["description"])]
                      for q in p["parameters"]])
    sys.stdout.write("\n".join(out))


if __name__ == "__main__":
    main()
