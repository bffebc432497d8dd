"""ThreadSanitizer workload for the core's parallel code, and the filter for
its reports. Run through `core/tools/sanitize.sh tsan` (which builds the core
with BSPLAB_SANITIZE=thread and preloads libtsan); not part of CI.

    python core/tools/tsan_check.py [--scenes room,spheres,fan] [--kd-scenes bunny]
                                    [--k 4] [--rays 20000]
        builds every method of bsplab.methods() with threads=2 on each scene
        of --scenes, and kd on those of --kd-scenes (parallel axes, parallel
        direction sweeps, subtree tasks), traces
        random rays with threads=2 (culling off and on), renders with
        threads=2, and cancels a build and a trace from another thread.
    python core/tools/tsan_check.py --filter LOGDIR
        reads TSan's report files in LOGDIR and keeps the reports with a
        frame in core/src (the core's own code); CPython, numpy and the
        uninstrumented runtime libraries can produce reports of their own,
        which are only counted. Exits 1 when a core report remains.
"""

from __future__ import annotations

import argparse
import collections
import os
import re
import sys
import threading
import time
from pathlib import Path

CORE_SRC = "/core/src/"


def load_scene(name: str):
    """A scene from scenes/ or the shared scenes; None when neither has it."""
    from bsplab import io, workloads

    repo = Path(__file__).resolve().parents[2]
    shared = workloads.shared_scenes_dir()
    for folder in [repo / "scenes"] + ([shared] if shared else []):
        if (folder / f"{name}.ply").exists():
            return io.load_mesh(folder / f"{name}.ply")
    print(f"tsan_check: no scene {name} (scenes/ or the shared scenes), skipped", flush=True)
    return None


def run(args) -> int:
    import bsplab
    from bsplab import workloads

    core = Path(bsplab._core.__file__).resolve()
    print(f"tsan_check: bsplab._core = {core}", flush=True)
    expected = os.environ.get("BSPLAB_EXPECT_CORE")  # set by sanitize.sh
    if expected and Path(expected).resolve() not in core.parents:
        print(f"tsan_check: bsplab._core is not the build in {expected}", file=sys.stderr)
        return 3
    methods = bsplab.methods()
    plan = [(s, list(methods)) for s in args.scenes.split(",") if s]
    plan += [(s, ["kd"]) for s in args.kd_scenes.split(",") if s]
    for name, which in plan:
        tris = load_scene(name)
        if tris is None:
            continue
        print(f"tsan_check: {name}: {len(tris)} triangles", flush=True)
        o, d = workloads.random_rays(tris, args.rays, seed=3)
        for method in which:
            info = methods[method]
            opts = {}
            if "k" in info["params"]:
                opts["k"] = max(args.k, info["min_k"] or 1)
            start = time.perf_counter()
            boxes = "clipped" if "+" in method or method == "kd" else "triangle"
            tree = bsplab.build(tris, method=method, threads=2, leaf_boxes=boxes, **opts)
            built = time.perf_counter() - start
            plain = tree.intersect(o, d, threads=2)
            culled = tree.intersect(o, d, threads=2, cull=True)
            assert (plain["prim"] == culled["prim"]).mean() > 0.999, method
            print(f"tsan_check:   {method:14s} {tree.stats['nodes']:8d} nodes, built in "
                  f"{built:6.1f} s", flush=True)
        cam = workloads.framing_camera(tris)
        bsplab.render(tree, cam, 96, 64, "heat_steps", threads=2)

    # Progress polled and a cancel sent from another thread while the core
    # works on two threads.
    tris = load_scene("spheres")
    for what in ("build", "trace"):
        p = bsplab.Progress()
        tree = bsplab.build(tris, threads=2) if what == "trace" else None

        def watch():
            while p.value == 0.0:
                time.sleep(0.001)
            p.cancel()

        w = threading.Thread(target=watch)
        w.start()
        try:
            if what == "build":
                bsplab.build(tris, method="bsp_wn+kd", k=4, threads=2, progress=p)
            else:
                o, d = workloads.random_rays(tris, 400_000, seed=5)
                tree.intersect(o, d, threads=2, progress=p)
            print(f"tsan_check: cancel: the {what} finished before the cancel", flush=True)
        except bsplab.Cancelled:
            print(f"tsan_check: cancel: the {what} stopped at {p.value:.3f}", flush=True)
        w.join()
    print("tsan_check: workload done", flush=True)
    return 0


REPORT = re.compile(r"^WARNING: ThreadSanitizer: (.*?)(?: \(pid=\d+\))?$")
FRAME = re.compile(r"^\s+#\d+ (.*)$")


def split_reports(text: str):
    """(kind, lines) for each report in a TSan log."""
    current = None
    for line in text.splitlines():
        m = REPORT.match(line)
        if m:
            current = (m.group(1), [line])
            continue
        if current is None:
            continue
        current[1].append(line)
        if line.startswith("SUMMARY: ThreadSanitizer"):
            yield current
            current = None


def filter_logs(logdir: Path) -> int:
    ours, others = [], collections.Counter()
    files = sorted(p for p in logdir.iterdir() if p.is_file())
    for f in files:
        for kind, lines in split_reports(f.read_text(errors="replace")):
            frames = [m.group(1) for ln in lines if (m := FRAME.match(ln))]
            if any(CORE_SRC in fr for fr in frames):
                ours.append((f.name, lines))
            else:
                summary = next((ln for ln in lines if ln.startswith("SUMMARY")), kind)
                others[summary] += 1
    for summary, n in others.most_common():
        print(f"tsan_check: {n} x outside the core: {summary}")
    for name, lines in ours:
        print(f"tsan_check: report in the core's code ({name}):")
        print("\n".join(lines))
    print(f"tsan_check: {len(files)} log file(s); {len(ours)} report(s) in core/src, "
          f"{sum(others.values())} elsewhere")
    return 1 if ours else 0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenes", default="room,spheres,fan",
                    help="every method on these: names in scenes/ or the shared scenes "
                         "(default: %(default)s)")
    ap.add_argument("--kd-scenes", default="bunny",
                    help="kd only on these (default: %(default)s, whose root has more than "
                         "the 65,536 triangles that split their axes in parallel; every "
                         "method on it takes about an hour under TSan)")
    ap.add_argument("--k", type=int, default=4, help="K for the methods that take one")
    ap.add_argument("--rays", type=int, default=20_000)
    ap.add_argument("--filter", type=Path, metavar="LOGDIR",
                    help="filter TSan's reports in LOGDIR instead of running the workload")
    args = ap.parse_args()
    if args.filter:
        return filter_logs(args.filter)
    return run(args)


if __name__ == "__main__":
    sys.exit(main())
