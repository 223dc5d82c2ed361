#!/usr/bin/env python3
"""Coverage per fuzz target from the edge lists a coverage-guided run writes (NAME.edges:
`address hit entry` per instrumented edge, see tests/src/coverage.rs).

Each edge's address is mapped to its source line with addr2line (binutils). For each target,
only the files of the reader it drives count (TARGET_FILES), and the figures are:
  functions: functions in those files the run entered / all instrumented functions there
             (writers and IO code in the same files are never entered by a reader's target);
  edges:     edges reached / all edges, inside the functions it entered;
  lines:     source lines reached / all instrumented lines of those files.
Usage: fuzz_coverage_report.py DIR   (prints a Markdown table)."""

import subprocess
import sys
from collections import defaultdict
from pathlib import Path

# The reader each target drives, as source paths relative to the workspace.
TARGET_FILES = {
    "bvh": ["sources/src/bvh/"],
    "gltf": ["sources/src/gltf/"],
    "recording": ["sources/src/recording/"],
    "config": ["server/src/config.rs", "server/src/config_error.rs"],
    "vmc": ["sources/src/vmc_in/"],
    "frame": ["protocol/src/frame.rs"],
    "http_head": ["server/src/http.rs", "server/src/access.rs"],
    "websocket": ["protocol/src/control.rs"],
}


def read_edges(path):
    lines = path.read_text().splitlines()
    exe = lines[0].lstrip("# ").strip()
    edges = []
    for line in lines[1:]:
        addr, hit, entry = line.split()
        edges.append((int(addr, 16), hit == "1", entry == "1"))
    return exe, edges


def symbolize(exe, addresses):
    """address -> (file, line), one addr2line run for all."""
    ordered = sorted(addresses)
    out = subprocess.run(
        ["addr2line", "-e", exe],
        input="\n".join(f"{a:x}" for a in ordered),
        capture_output=True,
        text=True,
        check=True,
    ).stdout.splitlines()
    where = {}
    for a, loc in zip(ordered, out):
        file, _, line = loc.rpartition(":")
        where[a] = (file, line.split(" ")[0])
    return where


def relative(file, prefixes):
    for p in prefixes:
        i = file.find("/" + p)
        if i >= 0:
            return file[i + 1 :]
    return None


def main():
    folder = Path(sys.argv[1])
    runs = {p.stem: read_edges(p) for p in sorted(folder.glob("*.edges"))}
    if not runs:
        sys.exit(f"no .edges files in {folder}")
    exe = next(iter(runs.values()))[0]
    # Every run lists the same edges in the same order (one executable).
    where = symbolize(exe, {a for _, edges in runs.values() for a, _, _ in edges})
    print("| target | functions entered | edges reached in them | lines reached | files |")
    print("|---|---|---|---|---|")
    for name, (_, edges) in runs.items():
        prefixes = TARGET_FILES.get(name)
        if prefixes is None:
            continue
        functions = []  # [entered, edges, edges hit] per function in the files
        lines = defaultdict(bool)
        files = set()
        current = None
        for addr, hit, entry in edges:
            file, line = where[addr]
            rel = relative(file, prefixes)
            if entry:
                current = [hit, 0, 0] if rel else None
                if current:
                    functions.append(current)
            if rel is None:
                continue
            files.add(rel)
            lines[(rel, line)] |= hit
            if current is not None:
                current[1] += 1
                current[2] += hit
        entered = [f for f in functions if f[0]]
        edges_in = sum(f[1] for f in entered)
        hit_in = sum(f[2] for f in entered)
        pct = lambda a, b: f"{a} / {b} ({100 * a / b:.0f} %)" if b else "0 / 0"
        print(
            f"| {name} | {pct(len(entered), len(functions))} | {pct(hit_in, edges_in)} | "
            f"{pct(sum(lines.values()), len(lines))} | {', '.join(sorted(files))} |"
        )


if __name__ == "__main__":
    main()
