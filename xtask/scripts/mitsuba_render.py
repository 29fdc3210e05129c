#!/usr/bin/env python3
"""Render and time a scene written by `cargo xtask reference --mitsuba DIR` with Mitsuba 3.

Usage: python3 xtask/scripts/mitsuba_render.py DIR [--variant scalar_rgb] [--threads N]
       [--repeats R] [--save-each]

Writes DIR/mitsuba.exr (the last repeat) and prints the load time and the median render
time of R repeats after one warm-up render (Mitsuba compiles nothing in its scalar
variants, but the first render pages in its libraries and the scene). Needs
`pip install mitsuba` (not a dependency of the toolkit: a cross-check only).
"""
import argparse
import statistics
import sys
import time
from pathlib import Path


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("dir", type=Path)
    ap.add_argument("--variant", default="scalar_rgb")
    ap.add_argument("--threads", type=int, default=0, help="0: every core")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--save-each", action="store_true",
                    help="also write each repeat as DIR/mitsuba.seed<K>.exr (for noise.py)")
    a = ap.parse_args()
    try:
        import mitsuba as mi
    except ImportError:
        print("mitsuba is not installed (pip install mitsuba)", file=sys.stderr)
        return 2
    mi.set_variant(a.variant)
    if a.threads > 0:
        mi.set_log_level(mi.LogLevel.Warn)
        import drjit as dr
        dr.set_thread_count(a.threads)
    t0 = time.perf_counter()
    scene = mi.load_file(str(a.dir / "scene.xml"))
    load = time.perf_counter() - t0
    image = mi.render(scene, seed=0)  # warm-up
    times = []
    for r in range(a.repeats):
        t0 = time.perf_counter()
        image = mi.render(scene, seed=r + 1)
        times.append(time.perf_counter() - t0)
        if a.save_each:
            mi.Bitmap(image).write(str(a.dir / f"mitsuba.seed{r + 1}.exr"))
    mi.Bitmap(image).write(str(a.dir / "mitsuba.exr"))
    print(f"mitsuba {a.variant}: load {load:.2f} s, render median {statistics.median(times):.2f} s "
          f"of {a.repeats} ({', '.join(f'{t:.2f}' for t in times)})")
    print(a.dir / "mitsuba.exr")
    return 0


if __name__ == "__main__":
    sys.exit(main())
