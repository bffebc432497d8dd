"""Command line: `python -m bsplab {demo,bench,bench-family,bench-families,bench-cull,bench-build,bench-instanced,experiment,
report,results,verdict,agree,calibrate,scenes,methods}`."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np


class DefaultPath(str):
    """An output path the command chose (an argparse default): its folder
    is created when missing. One the user gave must name an existing
    folder (output_file)."""


def output_file(path, flag: str, example: str, create_folder: bool = False) -> Path:
    """`path` as a file the command will write: refused up front (before any
    long work) when it is a directory, lies under a file, or - given by the
    user - lies in a folder that does not exist (a typo there would
    otherwise create a tree of folders silently). `create_folder`: the
    folder is the command's own choice (beside another output) and may be
    created."""
    p = Path(path)
    if p.is_dir():
        raise ValueError(f"{flag} {path} is a directory; give a file name such as "
                         f"{p / example}")
    _under_a_directory(p, flag)
    if not (create_folder or isinstance(path, DefaultPath)):
        _folder_exists(p.parent, flag, path)
    return p


def output_dir(path, flag: str) -> Path:
    """`path` as a directory the command will write into (and create); one
    the user gave must lie in an existing folder."""
    p = Path(path)
    if p.exists() and not p.is_dir():
        raise ValueError(f"{flag} {path} is a file; give a directory")
    _under_a_directory(p, flag)
    if not isinstance(path, DefaultPath):
        _folder_exists(p.parent, flag, path)
    return p


def _folder_exists(folder: Path, flag: str, path) -> None:
    if not folder.is_dir():
        raise ValueError(f"{flag} {path}: the folder {folder} does not exist; create it first "
                         "(an --out given is never created)")


def _under_a_directory(p: Path, flag: str) -> None:
    for parent in p.parents:  # the nearest one that exists must be a directory
        if parent.exists():
            if not parent.is_dir():
                raise ValueError(f"{flag} {p}: {parent} is a file, not a directory")
            return


def cmd_demo(args) -> int:
    import bsplab
    from bsplab import oracle, scenes, workloads
    from bsplab.image import write_png

    out = output_file(args.out, "--out", "demo.png")
    tris, camera = scenes.load_with_camera(args.scene)
    camera = camera or workloads.framing_camera(tris)
    print(f"scene {args.scene}: {len(tris):,} triangles; method {args.method}")
    progress = bsplab.Progress()
    tree = bsplab.build(tris, method=args.method, progress=progress)
    # Counted in every mode: the table shows the steps and tests per ray.
    image, rstats = bsplab.render(tree, camera, args.width, args.height, args.mode,
                                  threads=args.threads, counters=True)
    out.parent.mkdir(parents=True, exist_ok=True)
    write_png(out, image)
    s = tree.stats
    rows = [
        ("build time", f"{s['build_seconds']:.3f} s"),
        ("nodes (interior / leaves / empty)",
         f"{s['nodes']:,} ({s['interior_nodes']:,} / {s['leaves']:,} / {s['empty_leaves']:,})"),
        ("depth (max / limit / mean leaf)",
         f"{s['max_depth']} / {s['depth_limit']} / {s['mean_leaf_depth']:.1f}"),
        ("references (per triangle)", f"{s['references']:,} ({s['duplication']:.2f})"),
        ("triangles per leaf (mean / max)", f"{s['mean_leaf_size']:.2f} / {s['max_leaf_size']}"),
        ("degenerate triangles", f"{s['degenerate']:,}"),
        ("memory", f"{s['bytes'] / 2**20:.2f} MiB (nodes {s['node_bytes'] / 2**20:.2f} MiB; "
                   f"build peak {s['peak_bytes'] / 2**20:.2f} MiB)"),
        ("SAH cost", f"{s['sah_cost']:.2f}"),
        *(("WARNING", w) for w in s["warnings"]),
        ("render", f"{rstats['width']}x{rstats['height']} {rstats['mode']}, "
                   f"{rstats['seconds'] * 1e3:.1f} ms, {rstats['rays_per_second'] / 1e6:.2f} Mray/s"),
        ("steps / tests per ray", f"{rstats['mean_steps']:.1f} / {rstats['mean_tests']:.2f}"),
    ]
    if oracle.available():
        o, d = camera.rays(args.width, args.height)
        emb = oracle.EmbreeTracer(tris)
        ref = emb.intersect(o, d)
        start = time.perf_counter()
        ours = tree.intersect(o, d, threads=1, counters=False)  # hits only, as Embree
        t1 = time.perf_counter() - start
        c = oracle.compare(ours, ref, triangles=tris, origins=o, directions=d)
        rows += [
            ("Embree (same rays, 1 thread)",
             f"{emb.last_seconds * 1e3:.1f} ms; ours 1 thread {t1 * 1e3:.1f} ms "
             f"= {emb.last_seconds / t1:.2f}x Embree's speed"),
            ("agreement with Embree",
             f"{c['agreement'] * 100:.4f}% (disagreeing: {c['embree_wrong']} Embree wrong, "
             f"{c['grazing']} grazing, {c['bsplab_wrong']} ours wrong, "
             f"{c['undecided']} undecided)"),
        ]
    else:
        rows.append(("Embree", "embreex not installed: no comparison"))
    width = max(len(k) for k, _ in rows)
    for k, v in rows:
        print(f"  {k:<{width}}  {v}")
    print(f"image written to {out}")
    return 0


def _doc(args, example: str) -> Path | None:
    """The benchmark's --out, refused up front when it cannot be written."""
    if not args.out:
        return None
    out = output_file(args.out, "--out", example)
    for suffix in (".csv", ".json"):  # its rows: docs/data/<name>.csv and .json
        output_file((out.parent / "data" / out.stem).with_suffix(suffix), "--out's rows",
                    out.stem + suffix, create_folder=True)
    return out


def cmd_bench(args) -> int:
    from bsplab.lab import benchmarks
    return benchmarks.bench(_doc(args, "benchmark.md"), args.scenes, args.methods,
                            side=args.side, rays=args.rays, repeats=args.repeats)


def cmd_family(args) -> int:
    from bsplab.lab import benchmarks
    if not args.ks and args.kmin > args.kmax:
        raise ValueError(f"--kmin {args.kmin} is more than --kmax {args.kmax}: no K to run")
    ks = args.ks or list(range(args.kmin, args.kmax + 1))
    return benchmarks.bench_family(_doc(args, "bsp_benchmark.md"), args.scenes, args.methods,
                                   ks=ks, side=args.side, repeats=args.repeats)


def cmd_cull(args) -> int:
    from bsplab.lab import benchmarks
    return benchmarks.bench_cull(_doc(args, "cull_benchmark.md"), args.scenes, side=args.side,
                                 repeats=args.repeats)


def _write_page(text: str, out: Path | None) -> None:
    """A benchmark page: printed, and written to `out` when given."""
    print(text)
    if out is not None:
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(text)
        print(f"written {out}")


def cmd_build_bench(args) -> int:
    from bsplab.lab import build_bench
    from bsplab.cpu import cpu_features
    from bsplab.lab.store import load_average, machine_info
    out = output_file(args.out, "--out", "build_benchmark.md") if args.out else None
    machine = {**machine_info(), "isa": cpu_features()["supported"][-1],
               "started": time.strftime("%Y-%m-%d %H:%M:%S"), "load_start": load_average()}
    rows = build_bench.bench_build(args.scenes, rounds=args.repeats, threads=args.threads,
                                   sweeps=args.sweeps,
                                   side=build_bench.DEFAULT_SIDE if args.side is None else args.side)
    machine["load_end"] = load_average()
    if not rows:
        raise ValueError(f"none of the scenes ({', '.join(args.scenes or build_bench.DEFAULT_SCENES)}) "
                         f"is here (the shared scenes folder: {build_bench.shared_folder()}); "
                         "name generated scenes or mesh files with --scenes")
    text = build_bench.build_markdown(rows, "python -m bsplab " + " ".join(sys.argv[1:]), machine)
    _write_page(text, out)
    return 0


def cmd_instanced_bench(args) -> int:
    from bsplab.lab import instanced_bench
    out = output_file(args.out, "--out", "instanced_benchmark.md") if args.out else None
    rows = instanced_bench.bench_instanced(args.worlds, args.methods, side=args.side,
                                           rays=args.rays, rounds=args.repeats)
    text = instanced_bench.markdown(rows, "python -m bsplab " + " ".join(sys.argv[1:]))
    _write_page(text, out)
    return 0


def cmd_experiment(args) -> int:
    from bsplab import lab
    overrides = {"executor": args.executor, "workers": args.workers,
                 "scheduler": args.scheduler, "repetitions": args.repetitions}
    spec = lab.load_spec(args.spec, **overrides)
    given = args.out is not None
    out = Path(args.out or Path("out") / "experiments" / spec.name)
    if out.is_dir():
        raise ValueError(f"--out {out} is a directory; give a results path such as "
                         f"{out / spec.name} ({spec.name}.csv and .json are written there)")
    for suffix in (".csv", ".json"):
        output_file(out.with_suffix(suffix), "--out", spec.name + suffix,
                    create_folder=not given)
    if args.report:
        output_file(args.report, "--report", "report.md")
    rows = lab.run(spec, out, fresh=args.fresh)
    print(f"{len(rows)} rows in {out.with_suffix('.csv')} (run record: {out.with_suffix('.json')})")
    if args.report:
        write_report(rows, out, Path(args.report), spec.name)
    wrong = sum(int(r["unexplained"]) for r in rows if r["unexplained"] not in ("", None))
    if wrong:
        print(f"error: {wrong} rays disagree with Embree", file=sys.stderr)
    return 1 if wrong else 0


def write_report(rows, results_path: Path, md: Path, title: str) -> None:
    import json
    from bsplab.lab import plots, report
    meta_path = results_path.with_suffix(".json")
    meta = json.loads(meta_path.read_text()) if meta_path.exists() else None
    plot_dir = md.parent / (md.stem + "_plots")
    pngs = plots.plots(rows, plot_dir)
    md.parent.mkdir(parents=True, exist_ok=True)
    md.write_text(report.markdown(rows, title, meta, pngs, relative_to=md.parent))
    print(f"written {md} and {len(pngs)} plots in {plot_dir}")


def cmd_report(args) -> int:
    from bsplab import lab
    output_file(args.out, "--out", "report.md")
    rows = lab.read_rows(args.results)
    write_report(rows, Path(args.results), Path(args.out), args.title)
    return 0


def cmd_results(args) -> int:
    from bsplab.lab import results
    output_file(args.out, "--out", "results.md")
    return results.main(quick=args.quick, out=Path(args.out), fresh=not args.resume)


def cmd_verdict(args) -> int:
    from bsplab.lab import benchmarks, verdict_report
    out = output_file(args.out, "--out", "verdict.md")
    return verdict_report.main(out, args.scenes, args.results, rounds=args.rounds,
                               side=args.side, trace=not args.skip_trace,
                               command=benchmarks.command_line(), only_gap=args.only_gap)


def cmd_bench_families(args) -> int:
    import bsplab
    from bsplab.lab import family_bench
    methods = list(bsplab.methods()) if args.methods in (None, ["all"]) else args.methods
    rows = family_bench.run(args.scenes, methods, args.rays, k=args.k, rounds=args.repeats)
    bad = sum(r["leaks"] + r["unexplained"] + sum(r["paths"].values()) for r in rows)
    print(f"\n{bad} leaks, unexplained disagreements and path differences in {len(rows)} "
          "scene x method x family trials")
    return 1 if bad else 0


def cmd_agree(args) -> int:
    import bsplab
    from bsplab import agreement
    named = args.methods not in (None, [], ["all"])
    methods = args.methods if named else list(bsplab.methods())
    agreement.check_k(methods, args.k, named)
    rows = agreement.run(args.scenes, methods, args.rays, k=args.k, seed=args.seed)
    bad = sum(r["failing"] for r in rows)
    wrong = sum(r["embree_wrong"] for r in rows)
    print(f"\n{bad} failing rays (ours exactly wrong beyond rounding, or undecided) in "
          f"{len(rows)} scene x method x family trials; {wrong} where Embree is exactly wrong "
          "and ours is the exact answer")
    return 1 if bad else 0


def cmd_calibrate(args) -> int:
    from bsplab.lab import benchmarks, report
    fit = benchmarks.calibrate(args.scenes, repeats=args.repeats)
    print("\n".join(report.calibration_lines(fit)))
    if not fit["stable"]:
        print(f"  the ratios' IQR reaches beyond {benchmarks.STABLE_WITHIN:.0%} of the fit "
              "(a loaded machine?): more --repeats steady them")
    if args.write:
        from bsplab import costs
        try:
            path = costs.write_costs(fit)
        except ValueError as e:
            print(f"not written: {e}", file=sys.stderr)
            return 1
        print(f"written {path} (build(..., costs='measured') uses it)")
    return 0


def cmd_scenes(args) -> int:
    from bsplab import scenes
    scenes.main_write(output_dir(args.out, "--out"))
    return 0


def cmd_methods(args) -> int:
    import bsplab
    for name, info in bsplab.methods().items():
        print(f"{name:12} {info['label']:20} {info['description']}")
    return 0


class _Parser(argparse.ArgumentParser):
    """argparse with its errors on one line, like the commands' own."""

    def error(self, message):
        self.exit(2, f"error: {message} (see {self.prog} --help)\n")


def whole(low: int):
    """An argparse type: a whole number >= low."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
        if value < low:
            raise argparse.ArgumentTypeError(f"must be >= {low}, got {value}")
        return value
    return parse


def main(argv=None) -> int:
    from bsplab.render import RENDER_MODES
    p = _Parser(prog="python -m bsplab", description=__doc__)
    sub = p.add_subparsers(dest="command", required=True)

    d = sub.add_parser("demo", help="build a tree, render a preview PNG, print statistics")
    d.add_argument("--scene", default="spheres",
                   help="generated scene name, shared mesh name, or a .ply/.obj path")
    d.add_argument("--method", default="kd")
    d.add_argument("--mode", default="shaded", choices=RENDER_MODES)
    d.add_argument("--width", type=whole(1), default=640)
    d.add_argument("--height", type=whole(1), default=480)
    d.add_argument("--threads", type=whole(0), default=0, help="0: all cores")
    d.add_argument("--out", default=DefaultPath("out/demo.png"),
                   help="PNG to write, in an existing folder (default out/demo.png, its "
                        "folder created)")
    d.set_defaults(func=cmd_demo)

    b = sub.add_parser("bench", help="build and trace time against Embree")
    b.add_argument("--scenes", nargs="*", help="default: generated + all shared meshes")
    b.add_argument("--methods", nargs="*",
                   help="default: kd, bsp_cn+kd, bsp_wn+kd (K = 8: the spec's ks), bvh")
    b.add_argument("--side", type=whole(1), help="primary rays: side x side (default 512)")
    b.add_argument("--rays", type=whole(1), help="random rays (default 250,000)")
    b.add_argument("--repeats", type=whole(1), help="paired rounds (default 5)")
    b.add_argument("--out", help="write a Markdown report here (rows in data/ beside it)")
    b.set_defaults(func=cmd_bench)

    f = sub.add_parser("bench-family",
                       help="every BSP method at K = kmin..kmax against kd and Embree")
    f.add_argument("--scenes", nargs="+",
                   help="default: sponza_dabrovic conference sibenik bunny")
    f.add_argument("--methods", nargs="*", help="default: every method but kd")
    f.add_argument("--kmin", type=whole(1), default=3)
    f.add_argument("--kmax", type=whole(1), default=10)
    f.add_argument("--ks", type=whole(1), nargs="*",
                   help="explicit K values (instead of kmin..kmax)")
    f.add_argument("--side", type=whole(1), help="primary rays: side x side (default 384)")
    f.add_argument("--repeats", type=whole(1), help="paired rounds (default 3)")
    f.add_argument("--out", help="write Markdown here (rows in data/ beside it)")
    f.set_defaults(func=cmd_family)

    u = sub.add_parser("bench-cull", help="leaf culling on vs off, per scene and method")
    u.add_argument("--scenes", nargs="+",
                   help="default: sponza_dabrovic conference sibenik bunny")
    u.add_argument("--side", type=whole(1), help="primary rays: side x side (default 384)")
    u.add_argument("--repeats", type=whole(1), help="paired rounds (default 3)")
    u.add_argument("--out", help="write Markdown here (rows in data/ beside it)")
    u.set_defaults(func=cmd_cull)

    bf = sub.add_parser("bench-families",
                        help="per method and ray family: steps, tests, time / Embree, leaks, "
                             "and the paths' agreement")
    bf.add_argument("--scenes", nargs="+", default=["room", "spheres"])
    bf.add_argument("--methods", nargs="*", help="default: every method")
    bf.add_argument("--rays", type=whole(1), default=2000, help="rays per family")
    bf.add_argument("--k", type=whole(1), help="K of the methods that take one")
    bf.add_argument("--repeats", type=whole(1), default=3, help="paired rounds (default 3)")
    bf.set_defaults(func=cmd_bench_families)

    bb = sub.add_parser("bench-build", help="kd build time, exact and fast, against Embree's "
                                            "BVH build; what the fast build costs in the tree")
    bb.add_argument("--scenes", nargs="+", help="default: the seven shared meshes")
    bb.add_argument("--repeats", type=whole(1), default=3, help="paired rounds (default 3)")
    bb.add_argument("--threads", type=whole(0), default=0,
                    help="the second kd column's threads (default 0: all cores)")
    bb.add_argument("--sweeps", action="store_true",
                    help="also time bsp_wn+kd (K = 8) and bsp_ize+kd, as multiples of kd")
    bb.add_argument("--side", type=whole(0),
                    help="the quality table's primary rays: a side x side image, and one AO ray "
                         "from each hit (default 256; 0: no quality table)")
    bb.add_argument("--out", help="also write the Markdown table here")
    bb.set_defaults(func=cmd_build_bench)

    bi = sub.add_parser("bench-instanced",
                        help="instanced worlds: two levels against the flat tree and Embree")
    bi.add_argument("--worlds", nargs="+", help="default: grid25 suzanne_grid city forest spheres10k")
    bi.add_argument("--methods", nargs="+", help="the mesh trees' methods (default: kd bvh)")
    bi.add_argument("--side", type=whole(1), default=256, help="primary rays: side x side")
    bi.add_argument("--rays", type=whole(1), default=65_536, help="random rays")
    bi.add_argument("--repeats", type=whole(1), default=3, help="paired rounds (default 3)")
    bi.add_argument("--out", help="also write the Markdown page here")
    bi.set_defaults(func=cmd_instanced_bench)

    x = sub.add_parser("experiment", help="run an experiment spec (TOML or JSON), resumable")
    x.add_argument("spec", help="spec file; see docs/experiments.md")
    x.add_argument("--out", help="results path (.csv and .json written); default "
                                 "out/experiments/<name>")
    x.add_argument("--fresh", action="store_true", help="discard earlier results at --out")
    x.add_argument("--executor", choices=["process", "dask", "inline"])
    x.add_argument("--workers", type=whole(1), help="parallel trials")
    x.add_argument("--scheduler", help="dask scheduler address (default: a local cluster)")
    x.add_argument("--repetitions", type=whole(1))
    x.add_argument("--report", help="also write a Markdown report (and plots) here")
    x.set_defaults(func=cmd_experiment)

    r = sub.add_parser("report", help="Markdown tables and PNG plots of experiment results")
    r.add_argument("results", help="results .csv of `experiment`")
    r.add_argument("--out", required=True, help="Markdown file; plots go to <name>_plots/")
    r.add_argument("--title", default="Experiment results")
    r.set_defaults(func=cmd_report)

    q = sub.add_parser("results", help="regenerate docs/results.md and its plots")
    q.add_argument("--quick", action="store_true",
                   help="small scenes and few trials (for CI, under 3 minutes)")
    q.add_argument("--out", default=DefaultPath("docs/results.md"))
    q.add_argument("--resume", action="store_true",
                   help="keep the finished trials of an interrupted run")
    q.set_defaults(func=cmd_results)

    v = sub.add_parser("verdict", help="the experiments behind the results' discussion "
                                       "(docs/verdict.md)")
    v.add_argument("--scenes", nargs="+", help="default: the seven shared scenes here")
    v.add_argument("--results", default="docs/data/results.csv",
                   help="the results run whose rows sections 5-7 analyse")
    v.add_argument("--rounds", type=whole(1), default=7, help="paired rounds (default 7)")
    v.add_argument("--side", type=whole(1), help="primary rays: side x side (default: the "
                                                "results spec's 256)")
    v.add_argument("--skip-trace", action="store_true",
                   help="reuse the last traced record (docs/data/verdict.json)")
    v.add_argument("--only-gap", action="store_true",
                   help="reuse the last traced record's sections 1-4 and trace only section "
                        "8, the gap to Embree (kd, the best ^Kd, the BVH, Embree)")
    v.add_argument("--out", default=DefaultPath("docs/verdict.md"))
    v.set_defaults(func=cmd_verdict)

    a = sub.add_parser("agree", help="every method against Embree on the ray families "
                                     "(outside-in, axis-parallel, vertices, edges, planes, ...)")
    a.add_argument("--scenes", nargs="+", default=["room", "cube", "grids", "tilted"])
    a.add_argument("--methods", nargs="*", help="default: all")
    a.add_argument("--rays", type=whole(1), default=5000, help="rays per family")
    a.add_argument("--k", type=whole(1), help="K for the methods that take one (default: "
                                              "theirs); each must allow it")
    a.add_argument("--seed", type=int, default=0)
    a.set_defaults(func=cmd_agree)

    c = sub.add_parser("calibrate", help="fit the SAH costs to this machine's trace times")
    c.add_argument("--scenes", nargs="+", help="default: spheres room")
    c.add_argument("--repeats", type=whole(1), help="paired rounds (default 9)")
    c.add_argument("--write", action="store_true",
                   help="store the fitted costs in this machine's costs file "
                        "($BSPLAB_COSTS, else ~/.config/bsplab/costs.toml) for "
                        "build(..., costs='measured')")
    c.set_defaults(func=cmd_calibrate)

    s = sub.add_parser("scenes", help="(re)write the generated scenes as PLY files")
    s.add_argument("--out", default=DefaultPath("scenes"))
    s.set_defaults(func=cmd_scenes)

    m = sub.add_parser("methods", help="list the tree methods")
    m.set_defaults(func=cmd_methods)

    args = p.parse_args(argv)
    try:
        return args.func(args)
    except (ValueError, TypeError, RuntimeError) as e:
        print(f"error: {e}", file=sys.stderr)
    except MemoryError as e:
        print(f"error: out of memory{f': {e}' if str(e) else ''}", file=sys.stderr)
    except OSError as e:  # a file that cannot be read or written
        where = f"{e.filename}: " if e.filename and e.strerror else ""
        print(f"error: {where}{e.strerror or e}", file=sys.stderr)
    except KeyboardInterrupt:
        print("error: interrupted", file=sys.stderr)
        return 130
    return 2


if __name__ == "__main__":
    sys.exit(main())
