#!/usr/bin/env python3
"""The noise of a renderer's image, from two renders that differ only in their seed.

Usage: python3 xtask/scripts/noise.py A.exr B.exr [--seconds T]

For independent renders A and B of the same image, E[(A - B)^2] is twice the variance of
one render, pixel by pixel, whatever the image is: no converged reference is needed, and a
renderer's bias (or a small difference between two renderers' scenes) does not enter.
Prints, per channel, the mean over pixels of that variance and the relative RMS noise
(its square root over the image's mean). With `--seconds T`, the time one render took, it
also prints the work-normalised cost `T x variance` (lower is better): two renderers'
costs divide to "how many times longer one needs for the same noise", since a render's
variance falls as 1 / samples while its time grows as samples.
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
    ap.add_argument("a")
    ap.add_argument("b")
    ap.add_argument("--seconds", type=float)
    x = ap.parse_args()
    a, b = read(x.a), read(x.b)
    if a.shape != b.shape:
        print(f"sizes differ: {a.shape} and {b.shape}", file=sys.stderr)
        return 2
    var = ((a - b) ** 2).reshape(-1, 3).mean(axis=0) / 2.0
    mean = ((a + b) / 2.0).reshape(-1, 3).mean(axis=0)
    rel = np.sqrt(var) / mean
    print("variance of one render per channel: " + " / ".join(f"{v:.4e}" for v in var))
    print("relative RMS noise per channel:     " + " / ".join(f"{r:.4f}" for r in rel))
    if x.seconds:
        cost = x.seconds * var
        print(f"cost (seconds x variance) per channel: " + " / ".join(f"{c:.4e}" for c in cost)
              + f"  (mean {cost.mean():.4e})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
