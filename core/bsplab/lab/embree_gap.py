"""The gap to Embree, split into structure and kernel (docs/verdict.md,
section 8; issue 23).

Embree is a black box: a time and nothing to count. Our BVH is the structure
Embree builds (a binned-SAH bounding-volume hierarchy, collapsed to 8-wide
nodes as Embree's are), traced by our own kernel with our counters. So on the
same rays, in the same paired rounds, one thread, hits only:

* our BVH ÷ Embree is the price of our **kernel** (same kind of structure);
* kd ÷ our BVH and best ^Kd ÷ our BVH are the price of the **structure**
  (same kernel: the walk start, the triangle test, the tie rule);

and kd ÷ Embree = (kd ÷ BVH) × (BVH ÷ Embree) exactly, round by round. The
shares below split the logarithm of kd's gap: a structure share of 30 % means
kd ÷ BVH is kd ÷ Embree to the power 0.3. Counters (steps, box tests,
triangle tests per ray) come from one untimed trace on the counting path."""

from __future__ import annotations

import math

import numpy as np

from .spec import Spec, build_options, load_spec
from .timing import Tracer, paired_rounds
from .trials import load_scene, scene_references

# The trees, by label: (method, K). The best ^Kd is the faster of the two
# normal-based ^Kd trees per scene and rays (as docs/verdict.md's section 3).
KD, BVH, EMBREE = "kd", "bvh", "embree"
KD_TREES = {"bsp_wn+kd 8": ("bsp_wn+kd", 8), "bsp_cn+kd 8": ("bsp_cn+kd", 8)}
TREES = {KD: ("kd", None), **KD_TREES, BVH: ("bvh", None)}
WORKLOADS = ("primary", "random")
COUNTERS = ("steps", "box_tests", "tests")
# Below this kd ÷ Embree there is too little gap to split: its logarithm is
# within the rounds' noise, and a share of it reads as thousands of percent.
MIN_GAP = 1.10


def gap_spec(scenes: list[str], results_toml, **overrides) -> Spec:
    """The results spec's camera rays (and size) and as many random rays."""
    spec = load_spec(results_toml, scenes=scenes, methods=["kd"], workloads=list(WORKLOADS),
                     **overrides)
    spec.random_rays = spec.width * spec.height
    return spec


def _hits_only(tree, rays) -> Tracer:
    """The hits-only path with the rays in the given order: a kd or BSP tree
    would sort the random rays (ray_order="auto", the default), the BVH
    does not, and the split compares the structures' walks alone. What the
    spatial order buys is benchmark.md's (kd in both orders)."""
    return Tracer(lambda: tree.intersect(rays.origins, rays.directions, tmax=rays.tmax,
                                         threads=1, counters=False, ray_order="given"))


def _differs(a: dict, b: dict) -> int:
    """Rays on which two trees' answers differ (triangle or distance)."""
    return int(np.count_nonzero((a["prim"] != b["prim"]) | (a["t"] != b["t"])))


def trace_scene(spec: Spec, scene: str, rounds: int, trees=TREES) -> dict:
    """One scene's record: per workload, per tree its counters and its
    hits-only time in every round, and Embree's in the same rounds."""
    from .. import build
    data = load_scene(scene)
    embree, rays = scene_references(spec, scene, data)
    if embree is None:
        raise ValueError("the gap to Embree needs Embree (embreex), which is not usable here")
    built = {label: build(data.triangles, method=m, threads=spec.build_threads,
                          **build_options(spec, m, k)) for label, (m, k) in trees.items()}
    out = {"scene": scene, "triangles": len(data.triangles), "workloads": {}}
    for name, r in rays.items():
        etmax = None if np.isinf(r.tmax) else r.tmax
        tracers = {label: _hits_only(tree, r) for label, tree in built.items()}
        tracers[EMBREE] = Tracer(lambda r=r: embree.intersect(r.origins, r.directions,
                                                              tmax=etmax),
                                 lambda: embree.last_seconds)
        times = paired_rounds(tracers, rounds)
        counted = {label: tree.intersect(r.origins, r.directions, tmax=r.tmax, threads=1)
                   for label, tree in built.items()}
        out["workloads"][name] = {
            "rays": len(r.origins),
            "embree_seconds": times.seconds[EMBREE],
            "trees": {label: {"method": built[label].method,
                              "seconds": times.seconds[label],
                              **{c: float(counted[label][c].mean()) for c in COUNTERS},
                              "differs_from_kd": _differs(counted[label], counted[KD])}
                      for label in built}}
    return out


# --- the figures, from a record ------------------------------------------------

def ratio(workload: dict, a: str, b: str) -> float:
    """The median over the rounds of `a`'s time over `b`'s (labels of the
    record's trees, or EMBREE)."""
    def seconds(label):
        return np.asarray(workload["embree_seconds"] if label == EMBREE
                          else workload["trees"][label]["seconds"], dtype=np.float64)
    return float(np.median(seconds(a) / seconds(b)))


def best_kd(workload: dict) -> str:
    """The label of the faster normal-based ^Kd tree of the record."""
    labels = [label for label in KD_TREES if label in workload["trees"]]
    return min(labels, key=lambda label: ratio(workload, label, EMBREE))


def structure_share(workload: dict, tree: str = KD) -> float | None:
    """The share of log(tree ÷ Embree) that is log(tree ÷ BVH): the
    structure's part of the tree's gap (the rest is the kernel's). None when
    the tree is less than MIN_GAP times slower than Embree (no gap to split)."""
    gap = ratio(workload, tree, EMBREE)
    if gap < MIN_GAP:
        return None
    return math.log(ratio(workload, tree, BVH)) / math.log(gap)


def split(workload: dict) -> dict:
    """The section's figures for one scene and workload."""
    best = best_kd(workload)
    return {"kd_embree": ratio(workload, KD, EMBREE),
            "bvh_embree": ratio(workload, BVH, EMBREE),
            "kd_bvh": ratio(workload, KD, BVH),
            "best": best, "best_bvh": ratio(workload, best, BVH),
            "best_embree": ratio(workload, best, EMBREE),
            "kd_structure": structure_share(workload, KD)}


def _median(values) -> float | None:
    values = [v for v in values if v is not None]
    return float(np.median(values)) if values else None


def headline(scenes: list[dict]) -> str:
    """The section's first sentence, from the figures alone: medians over
    the record's scenes and workloads."""
    figures = [split(w) for s in scenes for w in s["workloads"].values()]
    if not figures:
        return "No scene was traced."
    kd_e = _median(f["kd_embree"] for f in figures)
    bvh_e = _median(f["bvh_embree"] for f in figures)
    kd_b = _median(f["kd_bvh"] for f in figures)
    best_b = _median(f["best_bvh"] for f in figures)
    share = _median(f["kd_structure"] for f in figures)
    where = (f"over {len(scenes)} scene{'s' if len(scenes) != 1 else ''} × "
             f"{len(figures) // max(len(scenes), 1)} ray sets (medians)")
    text = (f"kd takes {kd_e:.2f}× Embree's time {where}; our BVH, on the same kernel, "
            f"{bvh_e:.2f}×, and kd {kd_b:.2f}× our BVH's (the best ^Kd tree {best_b:.2f}×).")
    if share is None:
        return text + (f" kd is less than {MIN_GAP:.2f}× slower than Embree here: there is "
                       "no gap to split.")
    kernel = 1 - share
    split_text = (f" Of kd's gap to Embree (on a log scale), {100 * share:.0f} % is the "
                  f"structure (kd ÷ our BVH) and {100 * kernel:.0f} % the kernel (our BVH ÷ "
                  "Embree)")
    if share < 0:
        # kd's planes beat our BVH on our kernel: the kernel is more than the gap.
        return (text + split_text + ": none of it is the structure, since kd's planes beat "
                "our 8-wide BVH on the same kernel; the gap is the kernel's, and more.")
    if share > 1:
        return (text + split_text + ": all of it is the structure, since our BVH is faster "
                "than Embree.")
    lead = ("mostly the kernel" if kernel > 0.5 else "mostly the structure" if share > 0.5
            else "the structure and the kernel alike")
    return text + split_text + f": {lead}."


def _f(x, digits: int = 2) -> str:
    return "—" if x is None else f"{x:.{digits}f}"


def table(scenes: list[dict]) -> list[str]:
    """One row per scene and workload."""
    rows = []
    for s in scenes:
        for name, w in s["workloads"].items():
            f = split(w)
            t = w["trees"]
            kd, bvh, best = t[KD], t[BVH], t[f["best"]]
            share = f["kd_structure"]
            rows.append(
                f"| {s['scene']} | {name} | {f['kd_embree']:.2f} | {f['bvh_embree']:.2f} | "
                f"{f['kd_bvh']:.2f} | {f['best']}: {f['best_bvh']:.2f} | "
                f"{_f(None if share is None else 100 * share, 0)} | "
                f"{_f(None if share is None else 100 * (1 - share), 0)} | "
                f"{kd['steps']:.1f} / {best['steps']:.1f} / {bvh['steps']:.1f} | "
                f"{bvh['box_tests']:.1f} | "
                f"{kd['tests']:.2f} / {best['tests']:.2f} / {bvh['tests']:.2f} | "
                f"{bvh['differs_from_kd']} |")
    return ["| scene | rays | kd ÷ Embree | our BVH ÷ Embree (kernel) | kd ÷ our BVH "
            "(structure) | best ^Kd ÷ our BVH | structure % of kd's gap | kernel % | "
            "steps/ray kd / best / BVH | BVH box tests/ray | tests/ray kd / best / BVH | "
            "rays BVH ≠ kd |",
            "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|", *rows, ""]


def section(gap: dict | None, number: int) -> list[str]:
    """docs/verdict.md's section on the gap; says so when it was not traced."""
    out = [f"## {number}. The gap to Embree: structure or kernel", ""]
    if not gap or not gap.get("scenes"):
        return out + ["(Not traced: run `python -m bsplab verdict` or "
                      "`python -m bsplab verdict --only-gap`.)", ""]
    return out + [
        headline(gap["scenes"]), "",
        f"Traced: `{gap.get('command', '?')}`, {gap['width']}×{gap['height']} primary rays "
        f"from the results spec's camera and as many random rays (origins in the scene box, "
        f"directions on the sphere), {gap['rounds']} paired rounds with Embree, one thread, "
        f"the hits-only path with the rays in the given order (`ray_order=\"given\"`: the "
        f"split compares the walks alone, without the spatial order a kd or BSP tree would "
        f"give incoherent rays; benchmark.md shows kd in both orders); started "
        f"{gap.get('started', '?')}, "
        f"{gap.get('minutes', 0):.1f} min.", "",
        "Our BVH is a binned-SAH hierarchy collapsed into 8-wide nodes (one AVX test for "
        "eight child boxes, two SSE tests on CPUs without AVX) traced by this project's "
        "kernel; Embree's is 8 wide too, with its own 8-wide SIMD kernel. So `our BVH ÷ "
        "Embree` prices our kernel and layout against Embree's on the same kind of "
        "structure, and `kd ÷ our BVH` the structure on our kernel (binary planes against "
        "8-wide boxes: the width is part of it); their product is `kd ÷ Embree`, round by round. The "
        "shares split log(kd ÷ Embree): a negative structure share means kd's planes are "
        "faster than our BVH on our kernel (the kernel then accounts for more than the whole "
        f"gap); `—` where kd is less than {MIN_GAP:.2f}× slower than Embree (a gap within the "
        "rounds' noise: its share would read as thousands of percent). `rays BVH ≠ kd` "
        "counts rays on which the two answer differently (a triangle or a distance; ties of equal t go to the smallest index in "
        "both).", "",
        *table(gap["scenes"])]


def run(scenes: list[str], results_toml, rounds: int, log=print, **overrides) -> dict:
    """Every scene's record, as section() reads it."""
    import time

    from .store import load_average, machine_info
    spec = gap_spec(scenes, results_toml, **overrides)
    start = time.time()
    record = {"started": time.strftime("%Y-%m-%d %H:%M:%S"), "machine": machine_info(),
              "load_start": load_average(), "rounds": rounds, "width": spec.width,
              "height": spec.height, "scenes": []}
    for scene in spec.scenes:
        log(f"verdict, gap to Embree: {scene}")
        record["scenes"].append(trace_scene(spec, scene, rounds))
    record.update(minutes=round((time.time() - start) / 60, 1), load_end=load_average())
    return record
