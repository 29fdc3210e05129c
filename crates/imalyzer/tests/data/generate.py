#!/usr/bin/env python3
"""Generates the test images of imalyzer and the numbers its tests compare against.

    python3 -m venv /tmp/venv && /tmp/venv/bin/pip install scikit-image flip-evaluator numpy
    cd crates/imalyzer/tests/data && /tmp/venv/bin/python generate.py

Writes the small inputs (8-bit sRGB PNGs and uncompressed float EXRs, 64x48) and
expected.json: SSIM from scikit-image's structural_similarity, LDR-FLIP and HDR-FLIP from
NVIDIA's flip-evaluator, and the simple measures from numpy, computed the way
docs/imalyzer.md defines them. Run once; the Rust tests read the checked-in numbers.
"""
import json
import struct
import zlib
from importlib.metadata import version

import flip_evaluator as flip
import numpy as np
from skimage.metrics import structural_similarity

W, H = 64, 48
rng = np.random.default_rng(20240503)


# ---------------------------------------------------------------- file writers
def write_png(path, codes):
    """8-bit RGB PNG from an (H, W, 3) uint8 array (no dependency beyond zlib)."""
    h, w, _ = codes.shape
    raw = b"".join(b"\x00" + codes[y].tobytes() for y in range(h))

    def chunk(kind, data):
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body))

    ihdr = struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)
    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr)
                + chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b""))


def write_exr(path, rgb):
    """Scanline OpenEXR, 32-bit float R, G, B, no compression, from an (H, W, 3) array."""
    h, w, _ = rgb.shape
    rgb = rgb.astype("<f4")

    def attr(name, kind, data):
        return name.encode() + b"\0" + kind.encode() + b"\0" + struct.pack("<i", len(data)) + data

    chlist = b"".join(c.encode() + b"\0" + struct.pack("<iB3xii", 2, 0, 1, 1) for c in "BGR") + b"\0"
    box = struct.pack("<iiii", 0, 0, w - 1, h - 1)
    header = (struct.pack("<ii", 20000630, 2)
              + attr("channels", "chlist", chlist)
              + attr("compression", "compression", b"\0")
              + attr("dataWindow", "box2i", box)
              + attr("displayWindow", "box2i", box)
              + attr("lineOrder", "lineOrder", b"\0")
              + attr("pixelAspectRatio", "float", struct.pack("<f", 1.0))
              + attr("screenWindowCenter", "v2f", struct.pack("<ff", 0.0, 0.0))
              + attr("screenWindowWidth", "float", struct.pack("<f", 1.0))
              + b"\0")
    line_size = 3 * 4 * w
    start = len(header) + 8 * h
    offsets = b"".join(struct.pack("<Q", start + y * (8 + line_size)) for y in range(h))
    lines = b"".join(struct.pack("<ii", y, line_size)
                     + b"".join(rgb[y, :, c].tobytes() for c in (2, 1, 0))
                     for y in range(h))
    with open(path, "wb") as f:
        f.write(header + offsets + lines)


# ---------------------------------------------------------------- images
def srgb_to_linear(s):
    return np.where(s <= 0.04045, s / 12.92, ((s + 0.055) / 1.055) ** 2.4)


def to_codes(srgb):
    return np.clip(np.round(srgb * 255.0), 0, 255).astype(np.uint8)


y, x = np.mgrid[0:H, 0:W].astype(np.float64)
base = np.stack([0.15 + 0.6 * x / W, 0.2 + 0.5 * y / H, 0.7 - 0.4 * x / W], axis=-1)
base[10:30, 8:24] = [0.9, 0.3, 0.2]                                   # a red box
base[((x - 45) ** 2 + (y - 25) ** 2) < 100] = [0.2, 0.8, 0.3]         # a green disc
check = ((x // 2 + y // 2) % 2 == 0) & (y > 34) & (x > 30)
base[check] = [0.95, 0.95, 0.9]                                        # fine checker
base[38:44, 4:20] = [0.05, 0.05, 0.1]                                  # a dark bar
base += rng.normal(0.0, 0.01, base.shape)                              # a little texture
ref = to_codes(np.clip(base, 0, 1))

noisy = to_codes(np.clip(ref / 255.0 + rng.normal(0.0, 0.04, ref.shape), 0, 1))
k = np.array([1, 2, 1], np.float64) / 4
blurred = ref.astype(np.float64)
blurred = np.apply_along_axis(lambda r: np.convolve(np.pad(r, 1, mode="edge"), k, "valid"), 1, blurred)
blurred = np.apply_along_axis(lambda c: np.convolve(np.pad(c, 1, mode="edge"), k, "valid"), 0, blurred)
blurred = to_codes(blurred / 255.0)
shifted = np.roll(ref, 1, axis=1)
shifted = to_codes(np.clip(shifted / 255.0 * [0.92, 0.97, 1.05], 0, 1))

ldr = {"ref.png": ref, "noisy.png": noisy, "blurred.png": blurred, "shifted.png": shifted}
for name, img in ldr.items():
    write_png(name, img)

light = np.exp(-(((x - 20) ** 2) + ((y - 12) ** 2)) / 30.0)[..., None] * [40.0, 30.0, 20.0]
hdr_ref = (srgb_to_linear(ref / 255.0) * 2.0 + light).astype(np.float32)
hdr_noisy = (hdr_ref * rng.gamma(16.0, 1.0 / 16.0, hdr_ref.shape)).astype(np.float32)
hdr_noisy[5, 50] = [60.0, 60.0, 60.0]                                  # a firefly
hdr_noisy[40, 10] = [0.0, 0.0, 0.0]                                    # a dead pixel
hdr_dim = (hdr_ref * 0.8).astype(np.float32)
hdr = {"hdr_ref.exr": hdr_ref, "hdr_noisy.exr": hdr_noisy, "hdr_dim.exr": hdr_dim}
for name, img in hdr.items():
    write_exr(name, img)


# ---------------------------------------------------------------- measures
def linear_of(name):
    if name in ldr:
        return srgb_to_linear(ldr[name].astype(np.float64) / 255.0)
    return hdr[name].astype(np.float64)


def codes_of(lin):
    """Nearest 8-bit sRGB code of clamped linear values."""
    s = np.clip(lin, 0, 1)
    s = np.where(s <= 0.0031308, 12.92 * s, 1.055 * s ** (1 / 2.4) - 0.055)
    return np.round(s * 255.0)


def luminance(lin):
    return 0.27 * lin[..., 0] + 0.67 * lin[..., 1] + 0.06 * lin[..., 2]


def simple(a, b):
    d = np.abs(a - b)
    mse = np.mean((b - a) ** 2)
    return {
        "mean_error": d.mean(),
        "mean_error_8bit": np.abs(codes_of(a) - codes_of(b)).mean(),
        "pearson": np.corrcoef(a.ravel(), b.ravel())[0, 1],
        "rmse": np.sqrt(mse),
        "psnr": 10 * np.log10(1.0 / mse),
        "relmse": 0.5 * np.mean((b - a) ** 2 / (a ** 2 + 0.01)),
        "smape": np.mean(d / (np.abs(a) + np.abs(b) + 0.01)),
    }


def flip_input(name):
    if name in ldr:
        return ldr[name].astype(np.float32) / 255.0
    return hdr[name]


pairs = []
for ref_name, test_name in [("ref.png", "noisy.png"), ("ref.png", "blurred.png"),
                            ("ref.png", "shifted.png"), ("noisy.png", "blurred.png"),
                            ("hdr_ref.exr", "hdr_noisy.exr"), ("hdr_ref.exr", "hdr_dim.exr")]:
    a, b = linear_of(ref_name), linear_of(test_name)
    entry = {"reference": ref_name, "test": test_name}
    entry.update({k: float(v) for k, v in simple(a, b).items()})
    entry["ssim"] = float(structural_similarity(
        luminance(a), luminance(b), gaussian_weights=True, sigma=1.5,
        use_sample_covariance=False, K1=0.01, K2=0.03, data_range=1.0))
    if ref_name.endswith(".png"):
        _, mean, _ = flip.evaluate(flip_input(ref_name), flip_input(test_name), "LDR",
                                   inputsRGB=True, applyMagma=False)
        entry["flip"] = float(mean)
    else:
        _, mean, params = flip.evaluate(flip_input(ref_name), flip_input(test_name), "HDR",
                                        applyMagma=False)
        entry["hdr_flip"] = float(mean)
        entry["hdr_start_exposure"] = float(params["startExposure"])
        entry["hdr_stop_exposure"] = float(params["stopExposure"])
        entry["hdr_exposures"] = int(params["numExposures"])
        # LDR-FLIP of the linear values clamped to [0, 1], as imalyzer's LDR mode does.
        _, mean, _ = flip.evaluate(np.clip(hdr[ref_name], 0, 1), np.clip(hdr[test_name], 0, 1),
                                   "LDR", inputsRGB=False, applyMagma=False)
        entry["flip"] = float(mean)
    pairs.append(entry)

# Uniform images (linear values, 16x16): FLIP is the remapped colour difference alone.
uniform = []
for a, b in [(0.0, 1.0), (0.5, 0.25), (0.2, 0.21)]:
    A = np.full((16, 16, 3), a, np.float32)
    B = np.full((16, 16, 3), b, np.float32)
    _, mean, _ = flip.evaluate(A, B, "LDR", inputsRGB=False, applyMagma=False)
    uniform.append({"reference": a, "test": b, "flip": float(mean)})
# A white pixel at (8, 8) on black, 16x16 (linear values).
A = np.zeros((16, 16, 3), np.float32)
B = A.copy()
B[8, 8] = 1.0
fmap, mean, _ = flip.evaluate(A, B, "LDR", inputsRGB=False, applyMagma=False)
firefly = {"flip": float(mean), "flip_at_8_8": float(fmap[8, 8, 0]), "flip_max": float(fmap.max())}

out = {
    "command": "python3 generate.py (scikit-image %s, flip-evaluator %s, numpy %s)"
               % (version("scikit-image"), version("flip-evaluator"), version("numpy")),
    "ssim": "skimage structural_similarity(lum_ref, lum_test, gaussian_weights=True, sigma=1.5, "
            "use_sample_covariance=False, K1=0.01, K2=0.03, data_range=1.0) on "
            "0.27 R + 0.67 G + 0.06 B of linear values",
    "flip": "flip_evaluator.evaluate(ref, test, 'LDR' on sRGB PNG values | 'HDR' on linear EXR values)",
    "pairs": pairs,
    "uniform": uniform,
    "firefly": firefly,
}
with open("expected.json", "w") as f:
    json.dump(out, f, indent=1)
    f.write("\n")
print(json.dumps(out, indent=1))
