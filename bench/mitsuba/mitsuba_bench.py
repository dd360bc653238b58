#!/usr/bin/env python3
"""ember against Mitsuba 3 on the Cornell box: error against time, same machine, same run.

Run through ./run.sh, which makes the virtual environment, installs Mitsuba and LLVM, and
builds ember. Steps:

1. Convert data/cornell-box (TOML camera, OBJ objects, MTL albedos and Ke) to a Mitsuba XML
   scene: one OBJ per object, `diffuse` BSDFs, an `area` emitter on the light (one-sided, front
   = normal side, as in ember), a `perspective` sensor (fov_axis "y", look_at eye/at/up), a
   `box` pixel filter (ember's pixel sampling) and the `path` integrator with max_depth -1 and
   rr_depth 5 (ember's maxDepth -1, rrDepth 5; Mitsuba's roulette survival is throughput
   based, ember's is the scene's rrProb 0.95: same expectation, different variance per
   sample).
2. The reference: one long ember render with the `mis` integrator, made as SPLITS independent
   renders with their own seeds and averaged (their spread gives its noise). Mitsuba's `path`
   integrator is MIS path tracing (BSDF and emitter sampling, power heuristic), so ember's
   `mis` integrator is the one compared.
3. The same-image check: a long Mitsuba render (also SPLITS seeds) against the ember
   reference, by image mean and 8x8 block means, z = difference / sqrt(sum of the two
   variances), against the Student-t critical value at alpha = 0.01 shared by all tests
   (Sidak). Printed; a failure is reported and makes the script exit 1 (after writing
   everything), since comparing the speed of different images is meaningless.
4. Mitsuba ladders (scalar_rgb and llvm_ad_rgb, THREADS threads): 1, 2, 4, ... spp with a new
   seed per rung until a rung takes longer than the budget (a count the sampler rounds to one
   already rendered is skipped; rows record the count rendered); each rung is timed around
   mi.render (scene loading and an untimed warm-up render at the rung's count, which holds the
   LLVM compilation, excluded) and compared with `ember compare` against the reference, so both
   renderers' errors come from the same code. -> results.csv
5. `ember bench` on the same scene, film, threads and reference with --integrators mis,
   plotting Mitsuba's curves too. -> bench.csv, bench.svg
6. For equal relative MSE, ember's time over Mitsuba's, interpolated in log-log on each curve's
   lower envelope (a rung counts only if its error is below every faster rung's). -> table.md

With --rounds R (ROUNDS in run.sh), steps 4 and 5 are run R times, Mitsuba's ladders first in
even rounds and ember's first in odd ones, every round on the rungs of the first (same seeds,
so the same images and errors), and each rung keeps its fastest time. This instance's speed
drifts by 5-10% over minutes, for both renderers alike (2026-12-07: a ladder of one build took
9% longer in one window than minutes later), so a single pass can put the two renderers in
different windows; alternating the order and keeping the least disturbed time of each rung
gives both the same treatment.
"""
import argparse
import math
import os
import re
import shutil
import subprocess
import sys
import time
import tomllib

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.normpath(os.path.join(HERE, "..", ".."))
CSV_COLUMNS = "scene,integrator,spp,seconds,samples_per_second,rays_per_second,rmse,rel_mse,bias"


def log(msg):
    print(msg, flush=True)


# ----------------------------------------------------------------------------- conversion
def parse_mtl(path):
    """The MTL keys the conversion uses, with tinyobj's defaults for missing ones (Kd = Ks =
    Ke = 0, Ns = 1, Ni = 1, illum 0), Tf 1 1 1 and Pr absent (None)."""
    mats, cur = {}, None
    with open(path) as fh:
        for line in fh:
            p = line.split("#", 1)[0].split()
            if not p:
                continue
            if p[0] == "newmtl":
                cur = mats.setdefault(p[1], {
                    "Kd": [0.0] * 3, "Ks": [0.0] * 3, "Ke": [0.0] * 3, "Tf": [1.0] * 3,
                    "Ns": 1.0, "Ni": 1.0, "Pr": None, "illum": 0, "maps": [],
                })
            elif cur is None:
                continue
            elif p[0] in ("Kd", "Ks", "Ke", "Tf"):
                cur[p[0]] = [float(v) for v in p[1:4]]
            elif p[0] in ("Ns", "Ni", "Pr"):
                cur[p[0]] = float(p[1])
            elif p[0] == "illum":
                cur["illum"] = int(p[1])
            elif p[0] in ("map_Kd", "map_Ks"):
                cur["maps"].append(p[0])
    return mats


def bsdf_xml(name, m):
    """The Mitsuba BSDF of an MTL material under ember's mapping: illum 7 (or no specular
    part) diffuse Kd; illum 5 conductor with reflectance Ks at every angle (`material` none:
    no Fresnel), a mirror for Pr absent or 0, else `roughconductor` GGX with alpha = Pr^2;
    illum 6 dielectric with int_ior Ni, ext_ior 1 and specular_transmittance Tf, smooth for
    Pr absent or 0, else `roughdielectric` GGX alpha = Pr^2. TinyRender's Phong and mixture
    (illum 8 and others with Ks > 0) and texture maps have no Mitsuba equivalent: an error."""
    rgb = lambda v: ", ".join(repr(float(x)) for x in v)  # noqa: E731
    if m["maps"]:
        sys.exit(f"material {name}: texture maps ({', '.join(m['maps'])}) are not converted")
    illum, pr = m["illum"], m["Pr"]
    rough = pr is not None and pr > 0
    if illum == 5:
        ks = f'<rgb name="specular_reflectance" value="{rgb(m["Ks"])}"/>'
        if not rough:
            return f'<bsdf type="conductor"><string name="material" value="none"/>{ks}</bsdf>'
        return (f'<bsdf type="roughconductor"><string name="distribution" value="ggx"/>'
                f'<float name="alpha" value="{pr * pr!r}"/><string name="material" value="none"/>{ks}</bsdf>')
    if illum == 6:
        common = (f'<float name="int_ior" value="{m["Ni"]!r}"/><float name="ext_ior" value="1.0"/>'
                  f'<rgb name="specular_transmittance" value="{rgb(m["Tf"])}"/>')
        if not rough:
            return f'<bsdf type="dielectric">{common}</bsdf>'
        return (f'<bsdf type="roughdielectric"><string name="distribution" value="ggx"/>'
                f'<float name="alpha" value="{pr * pr!r}"/>{common}</bsdf>')
    if illum == 7 or max(m["Ks"]) == 0:
        return f'<bsdf type="diffuse"><rgb name="reflectance" value="{rgb(m["Kd"])}"/></bsdf>'
    sys.exit(f"material {name}: illum {illum} with Ks > 0 (TinyRender Phong/mixture) has no Mitsuba equivalent")


def split_obj(obj_path, out_dir):
    """Writes one OBJ per object (`o`), vertices and normals re-indexed, face order and
    winding kept. Returns [(object name, material, OBJ path)]."""
    vs, vns, objects = [], [], []
    mtllib, cur = None, None
    with open(obj_path) as fh:
        for line in fh:
            p = line.split()
            if not p:
                continue
            if p[0] == "v":
                vs.append(p[1:4])
            elif p[0] == "vn":
                vns.append(p[1:4])
            elif p[0] == "mtllib":
                mtllib = p[1]
            elif p[0] in ("o", "g"):
                cur = {"name": p[1], "material": None, "faces": []}
                objects.append(cur)
            elif p[0] == "usemtl":
                if cur is None:
                    cur = {"name": "default", "material": None, "faces": []}
                    objects.append(cur)
                cur["material"] = p[1]
            elif p[0] == "f":
                corners = []
                for tok in p[1:]:
                    parts = tok.split("/")
                    vi = int(parts[0])
                    ni = int(parts[2]) if len(parts) > 2 and parts[2] else None
                    if ni is None:
                        sys.exit(f"{obj_path}: faces need normals (f v//vn)")
                    vi = vi - 1 if vi > 0 else len(vs) + vi
                    ni = ni - 1 if ni > 0 else len(vns) + ni
                    corners.append((vi, ni))
                cur["faces"].append(corners)
    out = []
    for o in objects:
        if not o["faces"]:
            continue
        vmap, nmap, lines_v, lines_n, lines_f = {}, {}, [], [], []
        for face in o["faces"]:
            idx = []
            for vi, ni in face:
                if vi not in vmap:
                    vmap[vi] = len(vmap) + 1
                    lines_v.append("v " + " ".join(vs[vi]))
                if ni not in nmap:
                    nmap[ni] = len(nmap) + 1
                    lines_n.append("vn " + " ".join(vns[ni]))
                idx.append(f"{vmap[vi]}//{nmap[ni]}")
            lines_f.append("f " + " ".join(idx))
        path = os.path.join(out_dir, f"{o['name']}.obj")
        with open(path, "w") as fh:
            fh.write("\n".join([f"o {o['name']}"] + lines_v + lines_n + lines_f) + "\n")
        out.append((o["name"], o["material"], path))
    return out, mtllib


def convert(toml_path, out_dir, width, height=None):
    """The Mitsuba XML scene of a TinyRender path-traced scene at width x height (height
    defaults to width); returns (xml path, settings)."""
    height = width if height is None else height
    with open(toml_path, "rb") as fh:
        cfg = tomllib.load(fh)
    base = os.path.dirname(os.path.abspath(toml_path))
    obj = os.path.join(base, cfg["input"]["objfile"])
    cam, ren = cfg["camera"], cfg["renderer"]
    max_depth = int(ren.get("maxDepth", -1))
    rr_depth = int(ren.get("rrDepth", 5))
    os.makedirs(out_dir, exist_ok=True)
    objects, mtllib = split_obj(obj, out_dir)
    mats = parse_mtl(os.path.join(os.path.dirname(obj), mtllib))
    vec = lambda v: ", ".join(repr(float(x)) for x in v)  # noqa: E731
    rgb = lambda v: ", ".join(repr(float(x)) for x in v)  # noqa: E731
    shapes = []
    for name, mat, path in objects:
        m = mats[mat]
        emitter = ""
        if any(c > 0 for c in m["Ke"]):
            emitter = f'\n    <emitter type="area"><rgb name="radiance" value="{rgb(m["Ke"])}"/></emitter>'
        shapes.append(
            f"""  <shape type="obj" id="{name}">
    <string name="filename" value="{os.path.basename(path)}"/>
    {bsdf_xml(mat, m)}{emitter}
  </shape>"""
        )
    # Mitsuba counts the emitter vertex in max_depth (1 = emitters seen directly); TinyRender
    # counts scattering vertices (0 = emitters seen directly). -1 is unbounded in both.
    mi_depth = -1 if max_depth < 0 else max_depth + 1
    xml = f"""<scene version="3.0.0">
  <!-- Converted from {os.path.relpath(toml_path, ROOT)} by bench/mitsuba/mitsuba_bench.py -->
  <integrator type="path">
    <integer name="max_depth" value="{mi_depth}"/>
    <integer name="rr_depth" value="{rr_depth}"/>
  </integrator>
  <sensor type="perspective">
    <string name="fov_axis" value="y"/>
    <float name="fov" value="{float(cam["fov"])!r}"/>
    <transform name="to_world">
      <lookat origin="{vec(cam["eye"])}" target="{vec(cam["at"])}" up="{vec(cam["up"])}"/>
    </transform>
    <sampler type="independent"><integer name="sample_count" value="1"/></sampler>
    <film type="hdrfilm">
      <integer name="width" value="{width}"/>
      <integer name="height" value="{height}"/>
      <rfilter type="box"/>
      <string name="pixel_format" value="rgb"/>
    </film>
  </sensor>
{chr(10).join(shapes)}
</scene>
"""
    path = os.path.join(out_dir, "scene.xml")
    with open(path, "w") as fh:
        fh.write(xml)
    return path, {"max_depth": max_depth, "rr_depth": rr_depth, "objects": len(objects)}


def cpu_line():
    """The CPU model and its SIMD extensions (every speed figure has to carry them)."""
    model, flags = "unknown CPU", set()
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                key, _, value = line.partition(":")
                if key.strip() == "model name" and model == "unknown CPU":
                    model = value.strip()
                elif key.strip() == "flags" and not flags:
                    flags = set(value.split())
    except OSError:
        pass
    simd = [f for f in ("sse4_2", "avx", "avx2", "fma", "avx512f", "avx512dq", "avx512bw", "avx512vl") if f in flags]
    lanes = os.environ.get("EMBER_SIMD", "auto")
    return (f"CPU: {model}, {os.cpu_count()} logical cores; SIMD: {' '.join(simd) or 'none listed'}; "
            f"ember's lanes: EMBER_SIMD={lanes} (auto: AVX-512 where listed, else AVX2).")


# ----------------------------------------------------------------------------- statistics
def t_critical(alpha, dof):
    """Two-sided Student-t critical value: P(|T| > t) = alpha, by integrating the density."""
    c = math.exp(math.lgamma((dof + 1) / 2) - math.lgamma(dof / 2)) / math.sqrt(dof * math.pi)
    x = np.linspace(0.0, 60.0, 600_001)
    pdf = c * (1 + x * x / dof) ** (-(dof + 1) / 2)
    cdf = np.concatenate([[0.0], np.cumsum((pdf[1:] + pdf[:-1]) * 0.5 * (x[1] - x[0]))])
    tail = 2 * (0.5 - cdf)
    return float(x[np.argmax(tail < alpha)])


def block_means(img, blocks):
    h, w, _ = img.shape
    return img.reshape(blocks, h // blocks, blocks, w // blocks, 3).mean(axis=(1, 3))


def split_stats(splits, blocks):
    """Mean image, block means and the variance of each block mean (and of the image mean)
    from K independent equal renders."""
    k = len(splits)
    stack = np.stack(splits)
    mean = stack.mean(axis=0)
    b = np.stack([block_means(s, blocks) for s in splits])
    m = np.stack([s.reshape(-1, 3).mean(axis=0) for s in splits])
    return mean, b.mean(axis=0), b.var(axis=0, ddof=1) / k, m.mean(axis=0), m.var(axis=0, ddof=1) / k


def rel_mse(a, b):
    return float(np.mean((a - b) ** 2 / (b * b + 0.01)))


# ----------------------------------------------------------------------------- rendering
def read_exr(path):
    import mitsuba as mi

    return np.array(mi.Bitmap(path), dtype=np.float64)[:, :, :3]


def write_exr(path, img):
    import mitsuba as mi

    mi.Bitmap(np.ascontiguousarray(img, dtype=np.float32)).write(path)


def ember_compare(ember, image, reference):
    out = subprocess.run([ember, "compare", image, reference], capture_output=True, text=True)
    if out.returncode != 0:
        sys.exit(f"ember compare failed: {out.stderr}")
    vals = {}
    for line in out.stdout.splitlines():
        m = re.match(r"(rmse|rel_mse|bias)\s+([-+0-9.eE]+)", line)
        if m:
            vals[m.group(1)] = float(m.group(2))
    return vals


# What the llvm variants compile for, by --llvm-target: (LLVM CPU, feature flags, lanes), or
# None for Dr.Jit's own choice (this CPU: 16 lanes with AVX-512, 8 with AVX2). "avx2" stands in
# for an AVX2 machine on an AVX-512 one: Haswell's instruction set, AVX-512 off, 8 lanes.
LLVM_TARGETS = {
    "native": None,
    "avx2": ("haswell", "-avx512f,-avx512vl,-avx512dq,-avx512bw,-avx512cd,+avx2,+fma,+avx", 8),
}
LLVM_TARGET = None


def drjit_core():
    """Dr.Jit's core library (loaded by `import drjit`), for the target calls its Python
    bindings do not expose: jit_llvm_set_target and its getters (C++ symbols in drjit-core's
    jit.h)."""
    import ctypes
    import drjit as dr

    lib = ctypes.CDLL(os.path.join(os.path.dirname(dr.__file__), "libdrjit-core.so"))
    fns = {}
    for name, sym, res in (("cpu", "_Z19jit_llvm_target_cpuv", ctypes.c_char_p),
                           ("features", "_Z24jit_llvm_target_featuresv", ctypes.c_char_p),
                           ("width", "_Z21jit_llvm_vector_widthv", ctypes.c_uint32)):
        f = getattr(lib, sym)
        f.restype = res
        f.argtypes = []
        fns[name] = f
    f = lib._Z19jit_llvm_set_targetPKcS0_j
    f.argtypes = [ctypes.c_char_p, ctypes.c_char_p, ctypes.c_uint32]
    f.restype = None
    fns["set"] = f
    return fns


def llvm_target_line():
    """What the llvm variants compile for, read back from Dr.Jit."""
    core = drjit_core()
    features = core["features"]().decode()
    avx512 = "AVX-512 on" if "+avx512f" in features.split(",") else "AVX-512 off"
    return f"{core['cpu']().decode()}, {core['width']()} lanes, {avx512}"


def set_variant(variant, threads):
    import mitsuba as mi

    mi.set_variant(variant)
    import drjit as dr

    dr.set_thread_count(threads)
    if variant.startswith("llvm") and LLVM_TARGET is not None:
        cpu, features, width = LLVM_TARGET
        core = drjit_core()
        core["set"](cpu.encode(), features.encode(), width)
        if core["width"]() != width or core["cpu"]().decode() != cpu:
            sys.exit(f"error: Dr.Jit did not take the LLVM target {cpu} with {width} lanes")
    return mi, dr


def mitsuba_render(mi, dr, scene, spp, seed):
    img = mi.render(scene, spp=spp, seed=seed)
    arr = np.array(img, dtype=np.float64)  # forces evaluation (LLVM) and copies out
    return arr[:, :, :3]


def ladder(label, render, budget, max_spp, reference_path, ember, build, scene_name, pixels,
           effective_spp=lambda spp: spp):
    """Rungs of 1, 2, 4, ... requested spp until one takes longer than `budget`. A sampler may
    round the count up (Mitsuba's `ldsampler` and `stratified` to square powers of two,
    `orthogonal` to prime squares, `multijitter` to products of near-equal factors):
    `effective_spp(spp)` says what it renders, a rung that would repeat the count before it is
    skipped, and the row records the count rendered. Each rung is rendered twice with different
    seeds and the second render timed and compared: the first render at a new count can carry
    a one-off cost (the llvm variant's `ldsampler` kernels are compiled per sample count, which
    added 0.12 s to a 0.23 s render), and the steady-state time is the comparison most
    favourable to the other renderer."""
    rows, spp, rung, last = [], 1, 0, None
    while True:
        count = effective_spp(spp)
        if count != last:
            last = count
            render(spp, 1_000_000 + rung)  # warm-up at this count (untimed)
            t0 = time.perf_counter()
            img = render(spp, 1 + rung)
            seconds = time.perf_counter() - t0
            path = os.path.join(build, f"{label}_{count}spp.exr")
            write_exr(path, img)
            m = ember_compare(ember, path, reference_path)
            row = dict(
                scene=scene_name, integrator=label, spp=count, seconds=seconds,
                samples_per_second=pixels * count / seconds, rays_per_second=float("nan"),
                rmse=m["rmse"], rel_mse=m["rel_mse"], bias=m["bias"],
            )
            log(f"  {label:<22} {count:>6} spp {seconds:9.3f} s  {row['samples_per_second'] / 1e6:7.3f} Msamples/s"
                f"  rel_mse {row['rel_mse']:.4e}")
            rows.append(row)
            if seconds > budget or count > max_spp // 2:
                return rows
        spp *= 2
        rung += 1


def interp_time(points, target):
    """Time to reach relative MSE `target` on a curve of (seconds, rel_mse) points, linear in
    log-log between the two rungs around it; None outside the curve."""
    # The curve's lower envelope: a rung counts only if its error is below every faster
    # rung's, so the time to reach an error is the first time the curve gets there.
    pts = []
    for t, e in sorted(points, key=lambda p: p[0]):
        if not pts or e < pts[-1][1]:
            pts.append((t, e))
    for (t0, e0), (t1, e1) in zip(pts, pts[1:]):
        lo, hi = min(e0, e1), max(e0, e1)
        if lo <= target <= hi and e0 != e1:
            f = (math.log(target) - math.log(e0)) / (math.log(e1) - math.log(e0))
            return math.exp(math.log(t0) + f * (math.log(t1) - math.log(t0)))
    return None


# ----------------------------------------------------------------------------- main
def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--ember", required=True, help="the ember binary")
    ap.add_argument("--ember-native",
                    help="a second ember binary built with -C target-cpu=native (bit-identical images): its "
                         "ladders and tables follow the first's, files bench_native[_<sampler>].csv/.svg, since "
                         "Mitsuba's llvm variant also compiles for this CPU")
    ap.add_argument("--ember-native-name", default="target-cpu=native build",
                    help="what the second binary was built for, as the tables name it")
    ap.add_argument("--llvm-target", default="native", choices=sorted(LLVM_TARGETS),
                    help="what Mitsuba's llvm variants compile for: native (Dr.Jit's choice for this CPU) or "
                         "avx2 (Haswell's instruction set, 8 lanes: an AVX2 machine's code on this one)")
    ap.add_argument("--scene", default=os.path.join(ROOT, "data/cornell-box/cornell_box.toml"))
    ap.add_argument("--size", type=int, default=256, help="square film side (default for --width and --height)")
    ap.add_argument("--width", type=int, help="film width (default: --size)")
    ap.add_argument("--height", type=int, help="film height (default: --size)")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--ref-spp", type=int, default=4096, help="ember reference spp (total)")
    ap.add_argument("--mitsuba-ref-spp", type=int, default=4096, help="long Mitsuba render spp (total)")
    ap.add_argument("--splits", type=int, default=16, help="independent renders per long render")
    ap.add_argument("--budget", type=float, default=10.0, help="seconds: a ladder stops after the first slower rung")
    ap.add_argument("--max-spp", type=int, default=65536)
    ap.add_argument("--variants", default="scalar_rgb,llvm_ad_rgb")
    ap.add_argument("--mitsuba-samplers", default="independent",
                    help="comma-separated Mitsuba samplers, a ladder each per variant (independent, stratified, "
                         "multijitter, orthogonal, ldsampler)")
    ap.add_argument("--ember-samplers", default="independent",
                    help="comma-separated ember samplers, one ladder and table each (independent, zsobol); "
                         "ladders other than the independent one go to bench_<sampler>.csv/.svg")
    ap.add_argument("--rounds", type=int, default=1,
                    help="runs of every ladder, Mitsuba's and ember's first in turn; each rung keeps its "
                         "fastest time (the instance's speed drifts over minutes)")
    ap.add_argument("--out", default=HERE)
    args = ap.parse_args()
    if args.rounds < 1:
        sys.exit("--rounds must be at least 1")
    global LLVM_TARGET
    LLVM_TARGET = LLVM_TARGETS[args.llvm_target]

    build = os.path.join(args.out, "build")
    os.makedirs(build, exist_ok=True)
    scene_name = os.path.splitext(os.path.basename(args.scene))[0]
    width = args.width or args.size
    height = args.height or args.size
    pixels = width * height
    blocks = 8
    k = args.splits
    if width % blocks or height % blocks or args.ref_spp % k or args.mitsuba_ref_spp % k:
        sys.exit("the film sides must be multiples of 8 and the reference spp multiples of --splits")
    report = []

    def say(line=""):
        log(line)
        report.append(line)

    xml, info = convert(args.scene, build, width, height)
    say(f"# ember vs Mitsuba 3: {scene_name}, {width}x{height}, {args.threads} threads")
    say()
    say(cpu_line())
    say()
    say(f"Scene converted to {os.path.relpath(xml, args.out)} ({info['objects']} objects, "
        f"maxDepth {info['max_depth']}, rrDepth {info['rr_depth']}). Mitsuba's `path` integrator is MIS "
        "path tracing, so it is compared with ember's `mis` integrator.")

    # 2. The ember reference, as K independent renders.
    log(f"\n== ember reference: mis, {args.ref_spp} spp as {k} renders of {args.ref_spp // k} spp")
    t0 = time.perf_counter()
    splits = []
    for i in range(k):
        p = os.path.join(build, f"ember_ref_{i}.exr")
        subprocess.run(
            [args.ember, "render", args.scene, "--integrator", "mis", "--sampler", "independent",
             "--spp", str(args.ref_spp // k),
             "--seed", str(1000 + i), "--width", str(width), "--height", str(height),
             "--threads", str(args.threads), "-q", "-o", p],
            check=True, stderr=subprocess.DEVNULL)
        splits.append(read_exr(p))
    ref_seconds = time.perf_counter() - t0
    ref, ref_blocks, ref_bvar, ref_mean, ref_mvar = split_stats(splits, blocks)
    reference_path = os.path.join(build, "reference.exr")
    write_exr(reference_path, ref)
    half = k // 2
    ref_noise = rel_mse(np.mean(splits[:half], axis=0), np.mean(splits[half:], axis=0)) / 4
    say(f"\nReference: ember `mis`, {args.ref_spp} spp ({k} seeds x {args.ref_spp // k} spp), {ref_seconds:.0f} s; "
        f"its own noise, relMSE(half A, half B)/4 = {ref_noise:.3e}.")

    # 3. The long Mitsuba render and the same-image check.
    log(f"\n== Mitsuba long render: llvm_ad_rgb, {args.mitsuba_ref_spp} spp as {k} renders")
    variants = args.variants.split(",")
    long_variant = "llvm_ad_rgb" if "llvm_ad_rgb" in variants else variants[0]
    mi, dr = set_variant(long_variant, args.threads)
    if long_variant.startswith("llvm"):
        say()
        say(f"Mitsuba's llvm variants compile for: {llvm_target_line()}"
            + (" (--llvm-target avx2: an AVX2 machine's code, on this CPU)" if args.llvm_target == "avx2" else
               " (Dr.Jit's choice for this CPU)") + ".")
    scene = mi.load_file(xml)
    # Emitters are one-sided in both renderers (front = normal side): check that Mitsuba's OBJ
    # loader kept the winding, i.e. its face normals agree with the OBJ's vn.
    for shape in scene.shapes():
        if shape.is_emitter():
            ng = np.array([np.array(shape.face_normal(i), dtype=np.float64).ravel()
                           for i in range(shape.face_count())])
            vn = np.array(mi.traverse(shape)["vertex_normals"]).reshape(-1, 3)
            agree = bool(np.all(ng @ vn.mean(axis=0) > 0.99))
            say(f"\nEmitter `{shape.id()}` in Mitsuba: face normals {', '.join('(' + ', '.join(f'{c:g}' for c in v) + ')' for v in np.unique(ng.round(3) + 0.0, axis=0))}, "
                f"vertex normals {'agree' if agree else 'DISAGREE'} (one-sided emission faces the same way as in ember).")
            if not agree:
                sys.exit("error: Mitsuba's emitter faces the other way than ember's")
    msplits = [mitsuba_render(mi, dr, scene, args.mitsuba_ref_spp // k, 10_000 + i) for i in range(k)]
    mlong, m_blocks, m_bvar, m_mean, m_mvar = split_stats(msplits, blocks)
    write_exr(os.path.join(build, "mitsuba_long.exr"), mlong)
    tests = blocks * blocks * 3 + 3
    alpha = 1 - (1 - 0.01) ** (1 / tests)
    crit = t_critical(alpha, k - 1)
    z_mean = (m_mean - ref_mean) / np.sqrt(m_mvar + ref_mvar)
    z_blocks = (m_blocks - ref_blocks) / np.sqrt(m_bvar + ref_bvar)
    worst = np.unravel_index(np.argmax(np.abs(z_blocks)), z_blocks.shape)
    ok = bool(np.all(np.abs(z_mean) < crit) and np.all(np.abs(z_blocks) < crit))
    say("\n## Same image?\n")
    say(f"Mitsuba {long_variant} {args.mitsuba_ref_spp} spp against the ember reference; variances from the "
        f"{k} independent renders of each; critical |t| = {crit:.2f} (alpha 0.01 over {tests} tests, {k - 1} dof).")
    say()
    say(f"- image mean: Mitsuba ({', '.join(f'{v:.5f}' for v in m_mean)}), "
        f"ember ({', '.join(f'{v:.5f}' for v in ref_mean)}), z ({', '.join(f'{v:+.2f}' for v in z_mean)})")
    say(f"- 8x8 block means: max |z| = {np.abs(z_blocks).max():.2f} at block (row {worst[0]}, col {worst[1]}, "
        f"channel {worst[2]}); mean z^2 = {np.mean(z_blocks ** 2):.2f} (1 expected); "
        f"relative difference of block means: max {np.max(np.abs(m_blocks - ref_blocks) / np.maximum(ref_blocks, 1e-3)):.2%}")
    say(f"- verdict: {'SAME IMAGE within noise' if ok else 'DIFFERENT IMAGES: the timing comparison below is not valid'}")

    # 4. Mitsuba ladders: every variant with every sampler (the scene file's sampler swapped;
    # samplers that need square or prime-power counts round the ladder's spp their way, which
    # changes nothing here: only the measured time and error are compared).
    mitsuba_ladders = []  # (column name, ladder label, scene xml, variant)
    for msampler in args.mitsuba_samplers.split(","):
        sxml = xml
        if msampler != "independent":
            with open(xml) as fh:
                text = fh.read().replace('<sampler type="independent">', f'<sampler type="{msampler}">')
            sxml = os.path.join(build, f"scene_{msampler}.xml")
            with open(sxml, "w") as fh:
                fh.write(text)
        for variant in variants:
            name = variant if msampler == "independent" else f"{variant} {msampler}"
            label = f"mitsuba_{variant}" if msampler == "independent" else f"mitsuba_{variant}_{msampler}"
            mitsuba_ladders.append((name, label, sxml, variant))
    series = [(name, label) for name, label, _, _ in mitsuba_ladders]

    def run_mitsuba(round_no, last_spp):
        """One round of every Mitsuba ladder; from the second round on, the first's rungs."""
        rows = []
        for name, label, sxml, variant in mitsuba_ladders:
            log(f"\n== Mitsuba ladder: {name}, {args.threads} threads (round {round_no + 1} of {args.rounds})")
            mi, dr = set_variant(variant, args.threads)
            scene = mi.load_file(sxml)
            scene_sampler = scene.sensors()[0].sampler()

            def effective_spp(spp, scene_sampler=scene_sampler):
                scene_sampler.set_sample_count(spp)
                return scene_sampler.sample_count()

            budget, max_spp = args.budget, args.max_spp
            if label in last_spp:
                budget, max_spp = math.inf, last_spp[label]
            rows += ladder(label, lambda spp, seed: mitsuba_render(mi, dr, scene, spp, seed), budget,
                           max_spp, reference_path, args.ember, build, scene_name, pixels,
                           effective_spp)
        return rows

    builds = [("", args.ember, "baseline x86-64 build")]
    if args.ember_native:
        builds.append(("_native", args.ember_native, args.ember_native_name))
    ember_ladders = [(b, s) for b in builds for s in args.ember_samplers.split(",")]

    def ember_dir(build_suffix, sampler, round_no):
        suffix = build_suffix + ("" if sampler == "independent" else f"_{sampler}")
        return os.path.join(build, f"ember{suffix or '_independent'}_round{round_no + 1}")

    def run_ember(round_no, last_spp):
        """One round of every ember ladder (`ember bench`), each into a folder of its own."""
        for (build_suffix, ember, build_name), sampler in ember_ladders:
            out_dir = ember_dir(build_suffix, sampler, round_no)
            log(f"\n== ember bench: mis, {sampler} sampler, {build_name}, {args.threads} threads "
                f"(round {round_no + 1} of {args.rounds})")
            key = (build_suffix, sampler)
            budget, max_spp = args.budget, args.max_spp
            if key in last_spp:
                budget, max_spp = 1e9, last_spp[key]
            subprocess.run(
                [ember, "bench", args.scene, "--reference", reference_path, "--integrators", "mis",
                 "--threads", str(args.threads), "--budget", str(budget), "--max-spp", str(max_spp),
                 "--sampler", sampler, "--plot-also", os.path.join(args.out, "results.csv"), "-o", out_dir],
                check=True)

    def read_ember(build_suffix, sampler, round_no):
        with open(os.path.join(ember_dir(build_suffix, sampler, round_no), "bench.csv")) as fh:
            header = fh.readline().strip().split(",")
            return header, [dict(zip(header, line.strip().split(","))) for line in fh]

    def fastest_mitsuba(mitsuba_rounds):
        """Each rung of the first round with its fastest round's time (the same images and errors
        in every round), written to results.csv (which ember's plots read too)."""
        fastest = {}
        for rows_r in mitsuba_rounds:
            for r in rows_r:
                key = (r["integrator"], r["spp"])
                if key not in fastest or r["seconds"] < fastest[key]["seconds"]:
                    fastest[key] = r
        rows = []
        for r in mitsuba_rounds[0]:
            best = dict(fastest[(r["integrator"], r["spp"])])
            best["samples_per_second"] = pixels * best["spp"] / best["seconds"]
            rows.append(best)
        results = os.path.join(args.out, "results.csv")
        with open(results, "w") as fh:
            fh.write(CSV_COLUMNS + "\n")
            for r in rows:
                fh.write(f"{r['scene']},{r['integrator']},{r['spp']},{r['seconds']:.6f},{r['samples_per_second']:.1f},"
                         f"nan,{r['rmse']:.6e},{r['rel_mse']:.6e},{r['bias']:.6e}\n")
        log(f"wrote {results}")
        return rows

    # The rounds, the order alternating; the rungs of every round after the first are the first's.
    mitsuba_rounds = []
    last_mitsuba, last_ember = {}, {}
    for round_no in range(args.rounds):
        if round_no % 2 == 0:
            mitsuba_rounds.append(run_mitsuba(round_no, last_mitsuba))
            rows = fastest_mitsuba(mitsuba_rounds)
            run_ember(round_no, last_ember)
        else:
            run_ember(round_no, last_ember)
            mitsuba_rounds.append(run_mitsuba(round_no, last_mitsuba))
            rows = fastest_mitsuba(mitsuba_rounds)
        if round_no == 0:
            for r in mitsuba_rounds[0]:
                last_mitsuba[r["integrator"]] = max(last_mitsuba.get(r["integrator"], 0), r["spp"])
            for (build_suffix, _, _), sampler in ember_ladders:
                _, rows0 = read_ember(build_suffix, sampler, 0)
                last_ember[(build_suffix, sampler)] = max(int(r["spp"]) for r in rows0)

    # 5. ember's ladders (one per sampler) against the same reference, plotted with Mitsuba's:
    # each rung's fastest round in bench[_<build>][_<sampler>].csv; the plot is the first round's.
    curves = {name: [(r["seconds"], r["rel_mse"]) for r in rows if r["integrator"] == label] for name, label in series}
    for (build_suffix, ember, build_name), sampler in ember_ladders:
        suffix = build_suffix + ("" if sampler == "independent" else f"_{sampler}")
        header, ember_rows = read_ember(build_suffix, sampler, 0)
        for round_no in range(1, args.rounds):
            _, other = read_ember(build_suffix, sampler, round_no)
            by_spp = {r["spp"]: r for r in other}
            for i, r in enumerate(ember_rows):
                o = by_spp.get(r["spp"])
                if o is not None and float(o["seconds"]) < float(r["seconds"]):
                    ember_rows[i] = o
        with open(os.path.join(args.out, f"bench{suffix}.csv"), "w") as fh:
            fh.write(",".join(header) + "\n")
            for r in ember_rows:
                fh.write(",".join(r[h] for h in header) + "\n")
        shutil.copy(os.path.join(ember_dir(build_suffix, sampler, 0), "bench.svg"),
                    os.path.join(args.out, f"bench{suffix}.svg"))
        ember_pts = [(float(r["seconds"]), float(r["rel_mse"])) for r in ember_rows]

        # 6. Time ratios at equal error.
        say(f"\n## Time to equal relative MSE (ember `mis`, {sampler} sampler, {build_name})\n")
        say("ember `mis` time / Mitsuba time, interpolated linearly in log-log between ladder rungs "
            "on each curve's lower envelope (below 1: ember is faster); Mitsuba's rungs are timed "
            "warm, at the sample count its sampler renders"
            + (f"; each rung's time is the fastest of {args.rounds} rounds, run alternately" if args.rounds > 1 else "")
            + ". Every relative MSE includes the reference's own noise "
            f"({ref_noise:.1e}), so only errors above 10 times that are listed.")
        say()
        say("| relative MSE | ember mis (s) | " + " | ".join(f"{v} (s) | ratio" for v, _ in series) + " |")
        say("|---|---|" + "---|---|" * len(series))
        lo = max([min(e for _, e in ember_pts), 10 * ref_noise] + [min(e for _, e in c) for c in curves.values()])
        hi = min([max(e for _, e in ember_pts)] + [max(e for _, e in c) for c in curves.values()])
        targets = []
        if lo < hi:
            n = 6
            targets = [math.exp(math.log(hi) + (math.log(lo) - math.log(hi)) * i / (n - 1)) for i in range(n)]
        for target in targets:
            te = interp_time(ember_pts, target)
            cells = [f"{te:.3f}" if te else "-"]
            for v, _ in series:
                tm = interp_time(curves[v], target)
                cells += [f"{tm:.3f}", f"{te / tm:.2f}"] if te and tm else ["-", "-"]
            say(f"| {target:.3e} | " + " | ".join(cells) + " |")
        say()
    say(f"Measured {time.strftime('%Y-%m-%d %H:%M')} on {os.cpu_count()} cores; ladders stop after the first rung "
        f"over {args.budget} s. Curves: bench.svg; rows: bench.csv (ember), results.csv (Mitsuba).")
    with open(os.path.join(args.out, "table.md"), "w") as fh:
        fh.write("\n".join(report) + "\n")
    log(f"wrote {os.path.join(args.out, 'table.md')}")
    if not ok:
        log("error: Mitsuba and ember do not converge to the same image (see above)")
        sys.exit(1)


if __name__ == "__main__":
    main()
