#!/usr/bin/env python3
"""The noise of a renderer's image, from renders that differ only in their seed.

Usage: python3 xtask/scripts/noise.py A.exr B.exr [C.exr ...] [--seconds T]

For K independent renders of the same image, the per-pixel sample variance across them
(divided by K - 1) estimates the variance of one render, pixel by pixel, whatever the
image is: no converged reference is needed, a renderer's bias (or a small difference
between two renderers' scenes) does not enter, and it holds for stratified samplers,
whose per-sample variance over-states their error. Prints, per channel, the mean over
pixels of that variance and the relative RMS noise (its square root over the image's
mean). With `--seconds T`, the time one render took, it also prints the work-normalised
cost `T x variance` (lower is better): two renderers' costs divide to "how many times
longer one needs for the same noise", since a render's variance falls as 1 / samples
while its time grows as samples (for stratified samplers at least as fast).
"""
import argparse
import sys

import numpy as np


def read(path):
    import OpenEXR
    with OpenEXR.File(str(path)) as f:
        parts = f.channels()
        if "RGB" in parts:
            rgb = parts["RGB"].pixels
        else:
            rgb = np.stack([parts[c].pixels for c in ("R", "G", "B")], axis=-1)
    return np.asarray(rgb, dtype=np.float64)[..., :3]


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("renders", nargs="+")
    ap.add_argument("--seconds", type=float)
    x = ap.parse_args()
    if len(x.renders) < 2:
        print("give at least two renders", file=sys.stderr)
        return 2
    images = [read(p) for p in x.renders]
    if any(i.shape != images[0].shape for i in images):
        print(f"sizes differ: {[i.shape for i in images]}", file=sys.stderr)
        return 2
    stack = np.stack(images)
    var = stack.var(axis=0, ddof=1).reshape(-1, 3).mean(axis=0)
    mean = stack.mean(axis=0).reshape(-1, 3).mean(axis=0)
    rel = np.sqrt(var) / mean
    print(f"{len(images)} renders; variance of one render per channel: "
          + " / ".join(f"{v:.4e}" for v in var))
    print("relative RMS noise per channel: " + " / ".join(f"{r:.4f}" for r in rel))
    if x.seconds:
        cost = x.seconds * var
        print("cost (seconds x variance) per channel: " + " / ".join(f"{c:.4e}" for c in cost)
              + f"  (mean {cost.mean():.4e})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
