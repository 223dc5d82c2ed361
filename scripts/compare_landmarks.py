"""Compares two `rigcast pose --json` outputs of the same video, landmark by landmark, and
reports the acceptance figures of each.

Usage: compare_landmarks.py REFERENCE.json OTHER.json [more REFERENCE OTHER pairs...]

Per pair and over all pairs: person #0's image landmarks (33, pixels of the video) in frames
where both found them — mean and 95th-percentile distance in pixels and as a fraction of the
reference's torso size (shoulder midpoint to hip midpoint, that frame); and for each output the
coverage (frames with person #0), left/right swaps between consecutive frames (the hip or
shoulder line, world, reversing direction) and the worst limb-length coefficient of variation
(upper arms, thighs, shins, world) — the figures the pose2sim acceptance test checks.
"""
import json
import sys

import numpy as np

SEGMENTS = [(11, 13), (12, 14), (23, 25), (24, 26), (25, 27), (26, 28)]
LR_LINES = [(23, 24), (11, 12)]


def load(path):
    with open(path) as f:
        frames = json.load(f)["frames"]
    image = [np.array(fr["image"])[:, :2] if fr["image"] else None for fr in frames]
    world = [np.array(fr["world"]) if fr["world"] else None for fr in frames]
    return image, world


def figures(world):
    found = [w for w in world if w is not None]
    coverage = len(found) / max(len(world), 1)
    swaps = 0
    for a, b in zip(world, world[1:]):
        if a is None or b is None:
            continue
        swaps += any(np.dot(a[l] - a[r], b[l] - b[r]) <= 0 for l, r in LR_LINES)
    cvs = []
    for i, j in SEGMENTS:
        lengths = np.array([np.linalg.norm(w[i] - w[j]) for w in found])
        cvs.append(lengths.std() / lengths.mean() if len(lengths) else float("nan"))
    return coverage, swaps, max(cvs)


def deviations(ref, other):
    px, rel = [], []
    for a, b in zip(ref, other):
        if a is None or b is None:
            continue
        torso = np.linalg.norm((a[11] + a[12]) / 2 - (a[23] + a[24]) / 2)
        d = np.linalg.norm(a[:33] - b[:33], axis=1)
        px.extend(d)
        rel.extend(d / max(torso, 1e-6))
    return np.array(px), np.array(rel)


def describe(px, rel):
    if len(px) == 0:
        return "no frames in common"
    return (f"deviation mean {px.mean():.2f} px, p95 {np.percentile(px, 95):.2f} px; "
            f"of torso mean {rel.mean() * 100:.2f} %, p95 {np.percentile(rel, 95) * 100:.2f} %")


def main():
    paths = sys.argv[1:]
    if len(paths) < 2 or len(paths) % 2:
        sys.exit(__doc__)
    all_px, all_rel = [], []
    for ref_path, other_path in zip(paths[::2], paths[1::2]):
        (ref_img, ref_world), (img, world) = load(ref_path), load(other_path)
        px, rel = deviations(ref_img, img)
        all_px.append(px)
        all_rel.append(rel)
        for name, w in ((ref_path, ref_world), (other_path, world)):
            c, s, cv = figures(w)
            print(f"{name}: coverage {c * 100:.1f} %, swaps {s}, worst limb cv {cv * 100:.1f} %")
        print(f"  {describe(px, rel)}")
    print(f"all: {describe(np.concatenate(all_px), np.concatenate(all_rel))}")


if __name__ == "__main__":
    main()
