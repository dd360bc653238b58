#!/usr/bin/env python3
"""Mitsuba 3 references of ember's mirror/glass Cornell boxes, for tests/tests/mitsuba_materials.rs.

Run through ./materials.sh, which makes the virtual environment. For each scene (default:
data/mirror-glass/mirror_glass.toml and mirror_glass_rough.toml):

1. Converts the TinyRender scene to Mitsuba XML with mitsuba_bench.convert (illum 5 ->
   conductor / roughconductor with material "none" and specular_reflectance Ks, illum 6 ->
   dielectric / roughdielectric with int_ior Ni, ext_ior 1, specular_transmittance Tf, GGX
   alpha = Pr^2; illum 7 -> diffuse; the `path` integrator with max_depth = maxDepth + 1 for
   bounded depths, -1 here, and rr_depth = rrDepth).
2. Renders it SPLITS times with SPP samples per pixel, each with its own seed.
3. Writes <stem>_mitsuba_mean.exr (the mean of the renders) and <stem>_mitsuba_var.exr (the
   per-pixel variance of that mean: the sample variance over the renders / SPLITS), float32
   RGB, ZIP-compressed, and <stem>_mitsuba.json (how they were made).

The EXR writer is in this file (Mitsuba's Bitmap.write only writes PIZ); it is checked by
reading every file back with Mitsuba.
"""
import argparse
import json
import os
import platform
import struct
import sys
import time
import zlib

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.normpath(os.path.join(HERE, "..", ".."))
sys.path.insert(0, HERE)
import mitsuba_bench as mb  # noqa: E402

DEFAULT_SCENES = ["data/mirror-glass/mirror_glass.toml", "data/mirror-glass/mirror_glass_rough.toml"]


def log(msg):
    print(msg, flush=True)


# ----------------------------------------------------------------------------- EXR (ZIP)
def _attr(name, kind, data):
    return name.encode() + b"\0" + kind.encode() + b"\0" + struct.pack("<i", len(data)) + data


def write_exr_zip(path, img):
    """A scanline OpenEXR file of float32 R, G, B with ZIP compression (16 lines per chunk:
    byte interleaving, delta predictor, zlib), as the OpenEXR library writes it."""
    img = np.ascontiguousarray(img, dtype="<f4")
    h, w, _ = img.shape
    chans = b"".join(c.encode() + b"\0" + struct.pack("<iB3xii", 2, 0, 1, 1) for c in "BGR") + b"\0"
    box = struct.pack("<iiii", 0, 0, w - 1, h - 1)
    header = b"\x76\x2f\x31\x01" + struct.pack("<i", 2)
    header += _attr("channels", "chlist", chans)
    header += _attr("compression", "compression", b"\x03")  # ZIP_COMPRESSION
    header += _attr("dataWindow", "box2i", box)
    header += _attr("displayWindow", "box2i", box)
    header += _attr("lineOrder", "lineOrder", b"\x00")  # INCREASING_Y
    header += _attr("pixelAspectRatio", "float", struct.pack("<f", 1.0))
    header += _attr("screenWindowCenter", "v2f", struct.pack("<ff", 0.0, 0.0))
    header += _attr("screenWindowWidth", "float", struct.pack("<f", 1.0))
    header += b"\0"
    chunks = []
    for y0 in range(0, h, 16):
        rows = img[y0:y0 + 16]
        # Per scanline, the channels in alphabetical order (B, G, R), each a row of pixels.
        raw = np.ascontiguousarray(rows[:, :, ::-1].transpose(0, 2, 1)).tobytes()
        b = np.frombuffer(raw, dtype=np.uint8)
        inter = np.concatenate([b[0::2], b[1::2]])
        pred = inter.astype(np.int16)
        pred[1:] = (inter[1:].astype(np.int16) - inter[:-1].astype(np.int16) + 128) & 0xFF
        data = zlib.compress(pred.astype(np.uint8).tobytes(), 9)
        if len(data) >= len(raw):
            data = raw  # stored uncompressed when compression does not help (allowed by the format)
        chunks.append(struct.pack("<ii", y0, len(data)) + data)
    offsets, pos = [], len(header) + 8 * len(chunks)
    for c in chunks:
        offsets.append(pos)
        pos += len(c)
    with open(path, "wb") as fh:
        fh.write(header + struct.pack(f"<{len(offsets)}Q", *offsets) + b"".join(chunks))


# ----------------------------------------------------------------------------- main
def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scenes", nargs="*", default=DEFAULT_SCENES, help="TinyRender scene files (relative to the repository)")
    ap.add_argument("--width", type=int, default=160)
    ap.add_argument("--height", type=int, default=120)
    ap.add_argument("--splits", type=int, default=16, help="independent renders (seeds) per scene")
    ap.add_argument("--spp", type=int, default=256, help="samples per pixel of each render")
    ap.add_argument("--variant", default="scalar_rgb")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--seed", type=int, default=20261201, help="render i uses seed + 7919 * i")
    ap.add_argument("--out", default=os.path.join(HERE, "refs"))
    args = ap.parse_args()

    os.makedirs(args.out, exist_ok=True)
    mi, dr = mb.set_variant(args.variant, args.threads)
    for rel in args.scenes:
        toml = rel if os.path.isabs(rel) else os.path.join(ROOT, rel)
        stem = os.path.splitext(os.path.basename(toml))[0]
        build = os.path.join(HERE, "build", f"refs-{stem}")
        xml, info = mb.convert(toml, build, args.width, args.height)
        scene = mi.load_file(xml)
        seeds = [args.seed + 7919 * i for i in range(args.splits)]
        log(f"== {stem}: {args.variant}, {args.width}x{args.height}, {args.splits} renders x {args.spp} spp, "
            f"{args.threads} threads")
        t0 = time.perf_counter()
        renders = []
        for i, seed in enumerate(seeds):
            t = time.perf_counter()
            renders.append(mb.mitsuba_render(mi, dr, scene, args.spp, seed))
            log(f"  render {i + 1}/{args.splits} (seed {seed}): {time.perf_counter() - t:.1f} s, "
                f"mean {', '.join(f'{v:.5f}' for v in renders[-1].reshape(-1, 3).mean(axis=0))}")
        seconds = time.perf_counter() - t0
        stack = np.stack(renders)
        if not np.all(np.isfinite(stack)):
            sys.exit(f"{stem}: non-finite pixels in Mitsuba's renders")
        mean = stack.mean(axis=0)
        var = stack.var(axis=0, ddof=1) / args.splits
        paths = {}
        for kind, img in (("mean", mean), ("var", var)):
            paths[kind] = os.path.join(args.out, f"{stem}_mitsuba_{kind}.exr")
            write_exr_zip(paths[kind], img)
            back = np.array(mi.Bitmap(paths[kind]), dtype=np.float32)[:, :, :3]
            if not np.array_equal(back, img.astype(np.float32)):
                sys.exit(f"{paths[kind]}: reads back differently")
        per_render_means = stack.reshape(args.splits, -1, 3).mean(axis=1)
        meta = {
            "scene": os.path.relpath(toml, ROOT),
            "mitsuba": mi.__version__,
            "drjit": dr.__version__,
            "variant": args.variant,
            "integrator": {"type": "path", "max_depth": -1 if info["max_depth"] < 0 else info["max_depth"] + 1,
                           "rr_depth": info["rr_depth"]},
            "sampler": "independent",
            "rfilter": "box",
            "width": args.width,
            "height": args.height,
            "renders": args.splits,
            "spp_per_render": args.spp,
            "seeds": seeds,
            "threads": args.threads,
            "seconds": round(seconds, 1),
            "image_mean": [round(float(v), 6) for v in mean.reshape(-1, 3).mean(axis=0)],
            "image_mean_sd_from_renders": [round(float(v), 6) for v in per_render_means.std(axis=0, ddof=1)
                                           / np.sqrt(args.splits)],
            "image_mean_sd_from_pixel_variances": [round(float(v), 6) for v in np.sqrt(var.reshape(-1, 3).sum(axis=0))
                                                   / (args.width * args.height)],
            "cpu": mb.cpu_line(),
            "python": platform.python_version(),
            "files": {k: os.path.basename(p) for k, p in paths.items()},
        }
        with open(os.path.join(args.out, f"{stem}_mitsuba.json"), "w") as fh:
            json.dump(meta, fh, indent=2)
            fh.write("\n")
        log(f"  {seconds:.0f} s; image mean {meta['image_mean']}, sd {meta['image_mean_sd_from_renders']} "
            f"(from the renders) vs {meta['image_mean_sd_from_pixel_variances']} (from the pixel variances)")
        log(f"  wrote {paths['mean']}, {paths['var']}")


if __name__ == "__main__":
    main()
