#!/usr/bin/env python3
"""How much of the footage judge's figures is chance: one build's run as it is against its runs
under small perturbations of the decoded picture (issue 32, BENCHMARKS.md).

Each run is the judge's log (its table) and, beside it, the folder `RIGCAST_FOOTAGE_DUMP`
wrote. Per clip, the differences |as it is - perturbed| are summed over the perturbations:
coverage of every slot (points), identity jumps in the picture, left/right (points), MediaPipe's
person kept in some slot (points), and the slot-frames shown in one run only (from the dumps).
One flip that happens to go the right way under one perturbation does not decide: a tracker whose
decisions hinge on the rounding moves these sums, one that does not leaves them at zero.

    for n in none exact shift level deblock; do
      case $n in none) ;; exact) export RIGCAST_DECODE_EXACT_RGB=1;;
        *) unset RIGCAST_DECODE_EXACT_RGB; export RIGCAST_DECODE_NUDGE=$n;; esac
      RIGCAST_FOOTAGE_DUMP=runs/$n cargo test --release -p rigcast-sources --test vision_footage \\
        -- --exact footage_judge_reports_every_clip --nocapture > runs/$n.log 2>&1
    done
    scripts/footage_spread.py runs/none runs/exact runs/shift runs/level runs/deblock

Each argument RUN names RUN.log and the dump folder RUN (or RUN.dump); the first is the run as
it is.
"""
import json
import os
import sys


def table(log):
    """The judge's table: per clip, slot coverages, MediaPipe's person %, jumps, left/right %."""
    rows = {}
    for line in open(log, errors="replace"):
        if not line.startswith("| ") or line.startswith(("| clip", "|---")):
            continue
        cols = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cols) < 9:
            continue
        number = lambda s: None if s in ("-", "") else float(s)
        rows[cols[0]] = {
            "cov": [float(x) for x in cols[2].split("/")],
            "person": number(cols[4].split(",")[0]),
            "jumps": int(cols[5].split(",")[0]),
            "lr": number(cols[6].split(" ")[0]),
        }
    return rows


def dump_of(run):
    """The run's dump folder: RUN, else RUN.dump."""
    return run if os.path.isdir(run) else run + ".dump"


def one_run_only(dump_a, dump_b, clip):
    """Slot-frames seen in one of the two runs only (None without both dumps)."""
    names = [n for n in os.listdir(dump_a) if n.startswith(clip + ".")] if os.path.isdir(dump_a) else []
    if not names or not os.path.exists(os.path.join(dump_b, names[0])):
        return None
    a = json.load(open(os.path.join(dump_a, names[0])))
    b = json.load(open(os.path.join(dump_b, names[0])))
    return sum(
        (fa[s] is None) != (fb[s] is None) for fa, fb in zip(a, b) for s in range(len(fa))
    )


def gap(x, y):
    return 0.0 if x is None or y is None else abs(x - y)


def main(runs):
    base = table(runs[0] + ".log")
    others = [(r, table(r + ".log")) for r in runs[1:]]
    keys = ("cov", "jumps", "lr", "person", "frames")
    total = dict.fromkeys(keys, 0.0)
    moved = 0
    for clip, b in base.items():
        s = dict.fromkeys(keys, 0.0)
        for run, rows in others:
            p = rows.get(clip)
            if p is None:
                continue
            s["cov"] += sum(abs(x - y) for x, y in zip(b["cov"], p["cov"]))
            s["jumps"] += abs(b["jumps"] - p["jumps"])
            s["lr"] += gap(b["lr"], p["lr"])
            s["person"] += gap(b["person"], p["person"])
            s["frames"] += one_run_only(dump_of(runs[0]), dump_of(run), clip) or 0
        for k in keys:
            total[k] += s[k]
        if any(s.values()):
            moved += 1
            print(
                f"{clip[:32]:32} coverage {s['cov']:6.1f}  jumps {s['jumps']:3.0f}  "
                f"left/right {s['lr']:5.1f}  MediaPipe's person {s['person']:5.1f}  "
                f"slot-frames {s['frames']:4.0f}"
            )
    print(
        f"{len(others)} perturbations, {len(base)} clips, {moved} moved: coverage "
        f"{total['cov']:.1f} points, jumps {total['jumps']:.0f}, left/right {total['lr']:.1f} "
        f"points, MediaPipe's person {total['person']:.1f} points, slot-frames {total['frames']:.0f}"
    )


if __name__ == "__main__":
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    main(sys.argv[1:])
