#!/usr/bin/env python3
"""Embree's per-ray results on the bench-embree ray sets, for checking ember ray by ray.

    venv/bin/python embree_ref.py DATA_DIR [--scenes cbox,sphere_1k]

DATA_DIR is a bench-embree directory after `make_data.py` (scenes/bin/*.npy, rays/*.npy).
bench-embree's bench.py only writes results/ref/ from its native C harness, which is not
shipped, so with `--skip-native` nothing would be there; this script writes the same files
with embreex (Embree 4.4 through PyPI), in the layout bench.py's `compare_ref` reads:

  results/ref/<scene>_<set>_INTERSECT_prim.i32   int32 primitive id per ray, -1 = miss
  results/ref/<scene>_<set>_INTERSECT_t.f32      float32 hit distance (tfar on a miss)
  results/ref/<scene>_shadow_OCCLUDED_occ.u8     uint8, 1 = occluded

for set in camera, incoherent, shadow. results/ref/ uses Embree's default (non-robust) scene
flags, as bench.py's main table does; results/ref-robust/ the same with RTC_SCENE_FLAG_ROBUST.
Rays: tnear = 0; tfar = +inf for camera and incoherent (embreex's 1e37), the `tfar` file for
shadow rays.
"""
import argparse
import os
import sys
import time

import numpy as np
from embreex import mesh_construction as mc
from embreex import rtcore as rtc
from embreex import rtcore_scene as rtcs

SCENES = ["cbox", "sphere_1k", "sphere_10k", "sphere_100k", "sphere_1m"]
QUERIES = [("camera", "INTERSECT"), ("incoherent", "INTERSECT"), ("shadow", "INTERSECT"),
           ("shadow", "OCCLUDED")]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("data", help="bench-embree directory with scenes/ and rays/")
    ap.add_argument("--scenes", default=",".join(SCENES))
    args = ap.parse_args()
    for robust, sub in ((False, "ref"), (True, "ref-robust")):
        out = os.path.join(args.data, "results", sub)
        os.makedirs(out, exist_ok=True)
        for scene in args.scenes.split(","):
            t0 = time.time()
            V = np.load(os.path.join(args.data, "scenes", "bin", scene + "_V.npy"))
            F = np.load(os.path.join(args.data, "scenes", "bin", scene + "_F.npy"))
            sc = rtcs.EmbreeScene(rtc.EmbreeDevice(), robust=robust)
            mc.TriangleMesh(sc, V, F)
            summary = []
            for rayset, query in QUERIES:
                p = os.path.join(args.data, "rays", f"{scene}_{rayset}")
                O, D = np.load(p + "_origins.npy"), np.load(p + "_dirs.npy")
                tf = np.load(p + "_tfar.npy").copy() if rayset == "shadow" else None
                base = os.path.join(out, f"{scene}_{rayset}_{query}")
                if query == "INTERSECT":
                    r = sc.run(O, D, dists=tf, query=query, output=True)
                    r["primID"].astype(np.int32).tofile(base + "_prim.i32")
                    r["tfar"].astype(np.float32).tofile(base + "_t.f32")
                    summary.append(f"{rayset} hits {int((r['primID'] >= 0).sum())}")
                else:
                    occ = sc.run(O, D, dists=tf, query=query) == 0  # 0 = occluded, -1 = not
                    occ.astype(np.uint8).tofile(base + "_occ.u8")
                    summary.append(f"{rayset} occluded {int(occ.sum())}")
            print(f"{sub:10s} {scene:11s} {len(F):>9,} tris: {', '.join(summary)} ({time.time() - t0:.1f}s)",
                  flush=True)


if __name__ == "__main__":
    sys.exit(main())
