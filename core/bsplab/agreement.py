"""Every method's closest hits against Embree's on the ray families.

`python -m bsplab agree --scenes room --methods all` prints, per method and
family, how many rays fail the oracle (oracle.compare's "failing": our answer
exactly wrong beyond float rounding at an edge or at a segment's end, or
undecided), beside the rays where Embree is exactly wrong and ours is the
exact answer. The agreement tests call the same code.
"""

from __future__ import annotations

import numpy as np

from . import oracle, ray_families


# The families whose rays cross a surface through a shared edge or vertex
# lying in split planes, or come from far away: there a miss or a farther hit
# than Embree's is a leak (oracle.leaks). Rays along an edge or in a plane
# touch rather than cross; oracle.compare judges those.
CROSSING_FAMILIES = ("edges_in_split_planes", "through_edges", "far_away")


class FamilyRays:
    """The rays of every family on one scene, and Embree's answers, made once."""

    def __init__(self, triangles: np.ndarray, count: int, seed: int = 0,
                 families=None):
        self.triangles = triangles
        embree = oracle.EmbreeTracer(triangles)
        self.rays = {}
        for name in families or ray_families.FAMILIES:
            o, d, tmax = ray_families.family(name, triangles, count, seed)
            ref = embree.intersect(o, d, tmax=tmax)
            self.rays[name] = (o, d, tmax, ref)

    def check(self, tree, *, cull: bool = True, counters: bool = True) -> dict:
        """Per family: the oracle's comparison of the tree's hits with Embree's
        (`counters=False`: traced on the hits-only path), with "leaks" on the
        CROSSING_FAMILIES (an empty array on the others)."""
        out = {}
        for name, (o, d, tmax, ref) in self.rays.items():
            hits = tree.intersect(o, d, tmax=tmax, cull=cull, counters=counters)
            out[name] = oracle.compare(hits, ref, triangles=self.triangles, origins=o,
                                       directions=d, tmax=tmax)
            out[name]["hits"] = hits
            out[name]["leaks"] = (
                oracle.leaks(hits, ref, triangles=self.triangles, origins=o, directions=d,
                             tmax=tmax) if name in CROSSING_FAMILIES else np.zeros(0, int))
        return out


def check_k(methods: list[str], k: int | None, named: bool = True) -> None:
    """ValueError unless every method (a name of the method table) that
    takes K allows `k`, and, when the methods were `named` one by one, each
    takes a K at all (a --k for kd alone would be silently ignored)."""
    from .method_table import MAX_K, METHODS, get
    chosen = [get(m) for m in methods]  # unknown names are refused here
    if k is None:
        return
    without = [m.name for m in chosen if "k" not in m.params]
    if (named and without) or len(without) == len(chosen):
        raise ValueError(f"--k {k}: {', '.join(without)} "
                         f"{'takes' if len(without) == 1 else 'take'} no K (the methods that take "
                         f"K: {', '.join(n for n, m in METHODS.items() if 'k' in m.params)})")
    for m in chosen:
        if m.name not in without and not m.min_k <= k <= MAX_K:
            raise ValueError(f"--k {k} is out of range for {m.name}: it takes K in "
                             f"{m.min_k}..{MAX_K}")


def run(scenes: list[str], methods: list[str], count: int, k: int | None = None,
        seed: int = 0, out=print) -> list[dict]:
    """One row per scene, method and family; prints a table as it goes."""
    import bsplab
    from . import checks
    from .scenes import load

    checks.number(count, "rays per family", low=1, integer=True)
    check_k(methods, k, named=False)

    table = bsplab.methods()
    rows = []
    for scene in scenes:
        tris = load(scene)
        rays = FamilyRays(tris, count, seed)
        names = list(rays.rays)
        out(f"\n{scene}: {len(tris):,} triangles, {count:,} rays per family; "
            "failing rays (Embree wrong / grazing / at segment ends in brackets)")
        out(f"{'method':<16}" + "".join(f"{n[:14]:>16}" for n in names))
        for method in methods:
            opts = {}
            if k is not None and "k" in table[method]["params"]:
                opts["k"] = k
            tree = bsplab.build(tris, method=method, **opts)
            res = rays.check(tree)
            cells = []
            for name in names:
                c = res[name]
                rows.append({"scene": scene, "method": method, "family": name,
                             "rays": c["rays"], "failing": len(c["failing"]),
                             "bsplab_wrong": c["bsplab_wrong"], "undecided": c["undecided"],
                             "embree_wrong": c["embree_wrong"], "grazing": c["grazing"],
                             "at_ends": c["at_ends"]})
                cells.append(f"{len(c['failing'])} ({c['embree_wrong']}/{c['grazing']}/"
                             f"{c['at_ends']})")
            out(f"{method:<16}" + "".join(f"{c:>16}" for c in cells))
    return rows
