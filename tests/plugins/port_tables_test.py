#!/usr/bin/env python3
"""Every shipped plugin's ports are declared once, in its port table (kPorts, read here through
`lode plugins --json`). This test fails when a README's Ports table or a header's @system block
names other ports or other directions, when a plugin's folder, name and kind disagree, or when a
model (plant, sensor) claims ports.

Usage: port_tables_test.py LODE SOURCE_DIR"""
import json
import pathlib
import re
import subprocess
import sys

BLOCK_KINDS = {"source", "filter", "estimator", "controller", "io"}
MODEL_KINDS = {"plant", "sensor"}


def readme_ports(text):
    """(name, direction) of each row of the '## Ports' table."""
    m = re.search(r"^## Ports\s*$(.*?)(?=^## |\Z)", text, re.M | re.S)
    if not m:
        return None
    rows = [l for l in m.group(1).splitlines() if l.startswith("|")]
    ports = set()
    for row in rows[2:]:  # header and rule
        cells = [c.strip() for c in row.strip("|").split("|")]
        name = re.match(r"`?(<?[\w]+>?)`?", cells[0]).group(1)
        direction = re.match(r"(in|out)\b", cells[1]).group(1)
        ports.add((name, direction))
    return ports


def header_ports(text):
    """(name, direction) of the @system block's input_ports/output_ports, or None."""
    m = re.search(r"^// @system$(.*?)^// @endsystem$", text, re.M | re.S)
    if not m:
        return None
    ports, direction = set(), None
    for line in m.group(1).splitlines():
        head = re.match(r"^// (input_ports|output_ports):", line)
        if head:
            direction = "in" if head.group(1) == "input_ports" else "out"
            continue
        if re.match(r"^// \S", line):
            direction = None
            continue
        entry = re.match(r"^//   ?(<?\w+>?):", line)
        if entry and direction:
            ports.add((entry.group(1), direction))
    return ports


def main():
    lode, source = sys.argv[1], pathlib.Path(sys.argv[2])
    catalogue = json.loads(subprocess.run([lode, "plugins", "--json"], check=True, capture_output=True,
                                          text=True).stdout)
    by_name = {p["name"]: p for p in catalogue}
    problems, checked = [], 0
    for folder in sorted((source / "plugins").glob("*/*/")):
        if folder.name == "common" or not (folder / "CMakeLists.txt").exists():
            continue  # a family's shared code, not a plugin
        kind, short = folder.parent.name, folder.name
        name = f"{kind}.{short}"
        where = folder.relative_to(source)
        plugin = by_name.get(name)
        if plugin is None:
            problems.append(f"{where}: no plugin named {name} (the folder under plugins/ is the kind, "
                            f"its subfolder the rest of the name)")
            continue
        if plugin["kind"] != kind:
            problems.append(f"{where}: plugin {name} declares kind {plugin['kind']}, its folder says {kind}")
        declared = {(p["name"], p["direction"]) for p in plugin["ports"]}
        readme = (folder / "README.md").read_text()
        if not readme.startswith(f"# {name}\n"):
            problems.append(f"{where}/README.md: the title is not '# {name}'")
        if kind in MODEL_KINDS:
            if declared:
                problems.append(f"{name}: a model has no ports (its sides are inputs()/outputs()), "
                                f"but its table lists {sorted(declared)}")
            checked += 1
            continue
        documented = readme_ports(readme)
        if documented is None:
            problems.append(f"{where}/README.md: no '## Ports' table")
        elif documented != declared:
            problems.append(f"{where}/README.md: Ports table {sorted(documented)} != port table "
                            f"{sorted(declared)}")
        for header in sorted(folder.glob("*.hpp")):
            described = header_ports(header.read_text())
            if described is not None and described != declared:
                problems.append(f"{header.relative_to(source)}: @system ports {sorted(described)} != port "
                                f"table {sorted(declared)}")
        checked += 1
    for p in problems:
        print("FAIL", p)
    print(f"{checked} plugins checked, {len(problems)} disagreement(s)")
    return 1 if problems or checked == 0 else 0


if __name__ == "__main__":
    sys.exit(main())
