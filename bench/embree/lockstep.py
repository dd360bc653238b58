#!/usr/bin/env python3
"""Ratios of ray-query speed measured in lockstep: one pass of each side after the other,
round after round, so that both passes of a pair run within a second or two of each other.

Why: this shared 2-core instance drifts 10-30% within minutes, so two sides timed minutes apart
differ by the drift as much as by their code. Here each side stays resident for an epoch (ember
as `ember-bvh-embree --serve`, Embree through embreex in this process, timed exactly as
bench-embree's `bench.py` times it), and each round times one pass of every side in turn,
rotating who goes first. Two processes of one and the same binary also differ, by up to 8% with
intervals that exclude 1 (memory placement, which differs from process to process), so every
epoch starts fresh processes and BVHs: an epoch's ratio is the median of its rounds' ratios,
and a row's ratio is the median of its epochs' ratios with a distribution-free 95% confidence
interval over the epochs (order statistics of the binomial).

    lockstep.py DATA_DIR --scene cbox [--threads 1] [--epochs 8] [--rounds 5]
                [--ember NAME=BINARY ...] [--embree] [--robust] [--reference NAME]
                [--sets camera:INTERSECT,...] [--json F]

DATA_DIR: a bench-embree directory after make_data.py (bench/embree/run.sh's `$WORK/bench-embree`).
Sides: `--ember NAME=BINARY` (repeatable; an ember-bvh-embree build), `--embree` (embreex,
default mode), `--robust` (embreex with RTC_SCENE_FLAG_ROBUST). The reference (denominator) is
`--reference`, by default `embree` when timed, else the first ember side. With `--threads 1`
everything runs pinned to one CPU (this process before Embree's TBB starts, and the ember
processes it starts), as bench.py and run.sh pin their one-thread runs. Every ember process
must give the same per-ray results (hash) in every pass.
Needs numpy, and embreex for the Embree sides (run it with the venv that run.sh makes).
"""
import argparse
import json
import math
import os
import platform
import statistics
import subprocess
import sys
import time

import numpy as np

QUERIES = [("camera", "INTERSECT"), ("incoherent", "INTERSECT"), ("shadow", "INTERSECT"),
           ("shadow", "OCCLUDED")]
CHUNKS_2T = 32  # bench.py's two-thread split


def median_ci(xs, level=0.95):
    """Median of xs and the distribution-free interval [x_(k), x_(n-k+1)] that covers the
    population median with probability >= level (None where n is too small)."""
    xs = sorted(xs)
    n = len(xs)
    med = statistics.median(xs)
    alpha = (1.0 - level) / 2.0
    cdf, k = 0.0, 0
    while k < n:
        p = math.comb(n, k) / 2.0 ** n
        if cdf + p > alpha:
            break
        cdf += p
        k += 1
    if k == 0:
        return med, None, None
    return med, xs[k - 1], xs[n - k]


class Ember:
    def __init__(self, name, binary, data, scene):
        self.name = name
        self.proc = subprocess.Popen([binary, data, "--scenes", scene, "--serve"],
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True,
                                     bufsize=1)
        ready = self.proc.stdout.readline()
        if not ready.startswith("ready"):
            raise SystemExit(f"{binary}: did not start (`{ready.strip()}`)")
        self.info = ready.split(" ", 1)[1].strip()
        self.hashes = {}

    def run(self, rayset, query, threads):
        self.proc.stdin.write(f"{rayset} {query} {threads}\n")
        self.proc.stdin.flush()
        answer = self.proc.stdout.readline().split()
        if len(answer) != 2:
            raise SystemExit(f"{self.name}: no answer for {rayset} {query} {threads}")
        seconds, digest = float(answer[0]), answer[1]
        key = (rayset, query)
        if self.hashes.setdefault(key, digest) != digest:
            raise SystemExit(f"{self.name}: {rayset} {query} results changed between passes")
        return seconds

    def close(self):
        self.proc.stdin.write("\n")
        self.proc.stdin.flush()
        self.proc.wait()


class Embree:
    """One embreex scene timed as bench.py's `embreex_worker` times it."""

    def __init__(self, name, data, scene, robust):
        from embreex import mesh_construction as mc
        from embreex import rtcore as rtc
        from embreex import rtcore_scene as rtcs
        self.name = name
        V = np.load(os.path.join(data, "scenes", "bin", scene + "_V.npy"))
        F = np.load(os.path.join(data, "scenes", "bin", scene + "_F.npy"))
        self.device = rtc.EmbreeDevice()
        self.scene = rtcs.EmbreeScene(self.device, robust=robust)
        mc.TriangleMesh(self.scene, V, F)
        self.scene.run(np.zeros((1, 3), np.float32), np.array([[0.0, 0.0, 1.0]], np.float32))
        self.info = f"embreex, {'robust' if robust else 'default'} mode"
        self.pool = None

    def run(self, rays, query, threads):
        O, D, TF = rays
        tf = None if TF is None else TF.copy()  # run() may overwrite dists in place
        kw = dict(query=query, output=(query == "INTERSECT"))
        if threads == 2 and self.pool is None:
            from concurrent.futures import ThreadPoolExecutor
            self.pool = ThreadPoolExecutor(max_workers=2)
        t0 = time.perf_counter()
        if threads == 1:
            self.scene.run(O, D, dists=tf, **kw)
        else:
            bounds = np.linspace(0, len(O), CHUNKS_2T + 1).astype(int)
            futs = [self.pool.submit(self.scene.run, O[a:b], D[a:b],
                                     dists=None if tf is None else tf[a:b], **kw)
                    for a, b in zip(bounds[:-1], bounds[1:])]
            for f in futs:
                f.result()
        return time.perf_counter() - t0

    def close(self):
        if self.pool is not None:
            self.pool.shutdown()


def load_rays(data, scene, rayset):
    p = os.path.join(data, "rays", f"{scene}_{rayset}")
    tf = np.load(p + "_tfar.npy") if rayset == "shadow" else None
    return np.load(p + "_origins.npy"), np.load(p + "_dirs.npy"), tf


def cpu_line():
    model, flags = "", []
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name") and not model:
                    model = line.split(":", 1)[1].strip()
                elif line.startswith("flags"):
                    have = set(line.split(":", 1)[1].split())
                    flags = [f for f in ["sse4_2", "avx", "avx2", "fma", "avx512f", "avx512dq",
                                         "avx512bw", "avx512vl"] if f in have]
                    break
    except OSError:
        pass
    model = model or platform.processor() or "unknown CPU"
    return f"{model}, {os.cpu_count()} CPUs; SIMD: {' '.join(flags) or 'unknown'}"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("data")
    ap.add_argument("--scene", required=True)
    ap.add_argument("--threads", type=int, default=1, choices=[1, 2])
    ap.add_argument("--epochs", type=int, default=8)
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--ember", action="append", default=[], metavar="NAME=BINARY")
    ap.add_argument("--embree", action="store_true")
    ap.add_argument("--robust", action="store_true")
    ap.add_argument("--reference")
    ap.add_argument("--sets", help="comma-separated SET:QUERY (default: all four)")
    ap.add_argument("--json")
    a = ap.parse_args()
    if a.rounds < 1 or a.epochs < 1:
        raise SystemExit("--rounds and --epochs must be positive")
    if a.threads == 1:
        cpu = sorted(os.sched_getaffinity(0))[-1]
        os.sched_setaffinity(0, {cpu})  # before TBB starts and before the ember processes
    specs = []
    for spec in a.ember:
        name, _, binary = spec.partition("=")
        if not binary:
            raise SystemExit(f"--ember {spec}: expected NAME=BINARY")
        specs.append((name, binary))
    names = [n for n, _ in specs] + (["embree"] if a.embree else []) + \
        (["embree-robust"] if a.robust else [])
    if len(names) < 2:
        raise SystemExit("need at least two sides (--ember NAME=BIN, --embree, --robust)")
    if len(set(names)) != len(names):
        raise SystemExit("side names must differ")
    ref = a.reference or ("embree" if a.embree else names[0])
    if ref not in names:
        raise SystemExit(f"--reference {ref}: no such side")
    queries = QUERIES
    if a.sets:
        queries = [tuple(q.split(":")) for q in a.sets.split(",")]

    def start_sides():
        sides = [Ember(n, b, a.data, a.scene) for n, b in specs]
        if a.embree:
            sides.append(Embree("embree", a.data, a.scene, robust=False))
        if a.robust:
            sides.append(Embree("embree-robust", a.data, a.scene, robust=True))
        return sides

    print(f"# lockstep: {a.scene}, {a.threads} thread(s), {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}")
    print(f"CPU: {cpu_line()}" + (f"; pinned to CPU {sorted(os.sched_getaffinity(0))[0]}" if a.threads == 1 else ""))
    sides = start_sides()
    for s in sides:
        print(f"- {s.name}: {s.info}")
    print(f"\nRatio = side / {ref} in Mrays/s. {a.epochs} epochs, each with fresh processes "
          f"and BVHs and, per set, {a.rounds} rounds of one pass per side (the first side rotating); an epoch's "
          "ratio is the median of its rounds' ratios; shown: the median of the epochs' ratios and "
          "its distribution-free 95% confidence interval (over epochs, so that it includes what "
          "differs from one process to the next, such as where its memory lies).\n")
    print("| ray set | query | epochs x rounds | " + " | ".join(f"{n} Mrays/s" for n in names) + " | "
          + " | ".join(f"{n} / {ref} [95% CI]" for n in names if n != ref) + " |")
    print("|---|---|---:|" + "---:|" * (2 * len(names) - 1))
    records = []
    hashes = {}
    rays = {rayset: load_rays(a.data, a.scene, rayset) for rayset in dict.fromkeys(q[0] for q in queries)}
    times = {q: {n: [] for n in names} for q in queries}
    epoch_ratios = {q: {n: [] for n in names if n != ref} for q in queries}
    # Epochs outside, sets inside: one start of the processes serves every set.
    for epoch in range(a.epochs):
        if sides is None:
            sides = start_sides()
        for rayset, query in queries:

            def one(side):
                if isinstance(side, Ember):
                    return side.run(rayset, query, a.threads)
                return side.run(rays[rayset], query, a.threads)

            for s in sides:
                one(s)  # warm-up
            t = {n: [] for n in names}
            for r in range(a.rounds):
                k = (epoch * a.rounds + r) % len(sides)
                for s in sides[k:] + sides[:k]:
                    t[s.name].append(one(s))
            for n in names:
                times[(rayset, query)][n] += t[n]
                if n != ref:
                    epoch_ratios[(rayset, query)][n].append(statistics.median(
                        [t[ref][i] / t[n][i] for i in range(a.rounds)]))
        for s in sides:
            if isinstance(s, Ember):
                for key, digest in s.hashes.items():
                    if hashes.setdefault(key, digest) != digest:
                        raise SystemExit(f"{s.name}: {key} results differ from another side's")
            s.close()
        sides = None

    def fmt(c):
        m, lo, hi = c
        return f"{m:.3f} [{lo:.3f}–{hi:.3f}]" if lo is not None else f"{m:.3f}"

    for rayset, query in queries:
        q = (rayset, query)
        n_rays = len(rays[rayset][0])
        cis = {n: median_ci(v) for n, v in epoch_ratios[q].items()}
        mrays = {n: n_rays / statistics.median(times[q][n]) / 1e6 for n in names}
        print(f"| {rayset} | {query} | {a.epochs} x {a.rounds} | " + " | ".join(f"{mrays[n]:.2f}" for n in names)
              + " | " + " | ".join(fmt(cis[n]) for n in names if n != ref) + " |", flush=True)
        records.append(dict(scene=a.scene, rayset=rayset, query=query, threads=a.threads,
                            epochs=a.epochs, rounds=a.rounds, reference=ref, rays=n_rays,
                            times_s=times[q], epoch_ratios=epoch_ratios[q], mrays=mrays,
                            ratio={n: dict(zip(("median", "lo", "hi"), c)) for n, c in cis.items()}))
    if a.json:
        with open(a.json, "w") as f:
            for rec in records:
                f.write(json.dumps(rec) + "\n")


if __name__ == "__main__":
    sys.exit(main())
