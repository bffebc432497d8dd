"""Disagreements with Embree per ray family on the instanced test scenes, for
both trace paths: the table in docs/instances.md and the closing notes.

    python core/tools/instanced_families.py [--rays 1000]

On every scene of bsplab.instanced_scenes.TEST_SCENES, with kd, bvh and
bsp_wn+kd (K = 4) mesh trees, each family of bsplab.ray_families traced two
levels deep - single rays and packets - and by Embree over the flattened
scene. Per family: rays, rays whose triangle differs from Embree's (each
explained by a documented rule or an exact verdict when "failing" is 0),
failing rays (oracle.compare's "failing": ours exactly wrong beyond rounding,
or undecided) and leaks (oracle.compare and oracle.leaks with the transform's
slack, as test_instanced.py asserts), and the rays on which the packet path's
hit differs from the single-ray path's. About 5 minutes."""

from __future__ import annotations

import argparse

import numpy as np

import bsplab
from bsplab import instanced_scenes, oracle, ray_families

METHODS = {"kd": {}, "bvh": {}, "bsp_wn+kd": {"k": 4}}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--rays", type=int, default=1000, help="rays per family, scene and method")
    args = p.parse_args()
    # Per (family, packets): rays, prim differs, failing, leaks, differs from single.
    tot = {(f, packets): [0] * 5 for f in ray_families.FAMILIES for packets in (False, True)}
    for name in sorted(instanced_scenes.TEST_SCENES):
        meshes, idx, mats = instanced_scenes.TEST_SCENES[name]()
        for method, opts in METHODS.items():
            it = bsplab.build_instanced(meshes, idx, mats, method, **opts)
            flat = it.flatten()
            embree = oracle.EmbreeTracer(flat)
            for family in ray_families.FAMILIES:
                o, d, tmax = ray_families.family(family, flat, args.rays, seed=7)
                ref = embree.intersect(o, d, tmax=tmax)
                single = None
                for packets in (False, True):
                    ours = it.intersect(o, d, tmax=tmax, threads=1, counters=False,
                                        packets=packets)
                    single = ours if single is None else single
                    slack = np.maximum(
                        it.transform_slack(o, d, ours["t"], ours["instance"]),
                        it.transform_slack(o, d, ref["t"], it.instance_of(ref["prim"])))
                    hits = {"t": ours["t"], "prim": ours["flat_prim"].astype(np.int32)}
                    c = oracle.compare(hits, ref, triangles=flat, origins=o, directions=d,
                                       tmax=tmax, slack=slack)
                    leaked = oracle.leaks(hits, ref, triangles=flat, origins=o, directions=d,
                                          tmax=tmax, slack=slack)
                    differ = (ours["t"].view(np.uint32) != single["t"].view(np.uint32)) | (
                        ours["flat_prim"] != single["flat_prim"])
                    row = tot[(family, packets)]
                    row[0] += len(o)
                    row[1] += int((hits["prim"] != ref["prim"]).sum())
                    row[2] += len(c["failing"])
                    row[3] += len(leaked)
                    row[4] += int(differ.sum())
    print("| family | rays | prim differs (single / packets) | failing | leaks "
          "| packets differ from single |")
    print("|---|---:|---:|---:|---:|---:|")
    for family in ray_families.FAMILIES:
        a, b = tot[(family, False)], tot[(family, True)]
        print(f"| {family} | {a[0]:,} | {a[1]} / {b[1]} | {a[2]} / {b[2]} | {a[3]} / {b[3]} "
              f"| {b[4]} |")


if __name__ == "__main__":
    main()
