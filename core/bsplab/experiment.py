"""The experiment runner: a spec (scenes x methods x K x seeds, a workload,
repetitions) expands into cells; each cell builds one tree and traces every
workload `repetitions` times, each time right beside Embree on the same rays,
so that every time has a same-process reference. Rows go to a CSV file as
cells finish (a JSON file beside it records the machine, the versions and
the spec), and a rerun with the same spec skips the cells already there.

Counters (steps, tests, node counts) are exact and machine-independent:
they are what make sweeps run on several machines comparable. Times are
compared only within one machine, as ratios to Embree's time measured in
the same cell.
"""

from __future__ import annotations

import csv
import hashlib
import json
import os
import platform
import sys
import time
from dataclasses import MISSING, asdict, dataclass, field, fields
from pathlib import Path
from typing import Callable, Iterable

import numpy as np

from .method_table import MAX_K, METHODS

WORKLOADS = ("primary", "ao", "diffuse")
EXECUTORS = ("process", "dask", "inline")

ROW_FIELDS = [
    "scene", "triangles", "method", "k", "seed", "workload", "rays",
    "build_s", "nodes", "kd_nodes", "general_nodes", "leaves", "refs_per_tri", "bytes",
    "sah", "level_planes", "level_directions",
    "trace_s", "kd_s", "embree_s", "steps", "general_steps", "tests", "hits", "unexplained",
    "grazing", "embree_build_s",
]


class SpecError(ValueError):
    """A spec that cannot run; the message says what to fix."""


# -----------------------------------------------------------------------------
# Specs


@dataclass
class Spec:
    """The keys of a spec file, their defaults (docs/experiments.md explains them)."""
    name: str = "experiment"
    scenes: list = field(default_factory=list)   # generated, shared, .ply/.obj/.blend
    methods: list = field(default_factory=lambda: ["kd"])
    ks: list = field(default_factory=lambda: [6])
    method_ks: dict = field(default_factory=dict)  # per-method K lists replacing `ks`
    seeds: list = field(default_factory=lambda: [1])
    repetitions: int = 7          # traces per tree; the thesis ran 7 (min/med/max)
    workloads: list = field(default_factory=lambda: ["primary", "ao"])
    width: int = 256              # primary rays: width x height from the scene's camera
    height: int = 256
    ao_samples: int = 1           # secondary rays per primary hit
    ao_distance: float = 0.1      # AO ray length / the scene box's diagonal
    options: dict = field(default_factory=dict)  # build options for every method
    build_threads: int = 0        # 0: all cores
    executor: str = "process"
    workers: int = 1              # parallel cells (more than 1 disturbs the timings)
    scheduler: str = ""           # dask: a running scheduler's address; "": local cluster

    def fingerprint(self) -> str:
        """What decides the rows (not how they are run): resume only matches this."""
        d = asdict(self)
        for k in ("executor", "workers", "scheduler", "name", "build_threads"):
            d.pop(k)
        return hashlib.sha1(json.dumps(d, sort_keys=True).encode()).hexdigest()[:12]

    def ks_of(self, method: str) -> list:
        if "k" not in METHODS[method].params:
            return [None]
        return list(self.method_ks.get(method, self.ks))

    def seeds_of(self, method: str) -> list:
        return list(self.seeds) if "seed" in METHODS[method].params else [self.seeds[0]]


SPEC_DEFAULTS = {f.name: f.default if f.default_factory is MISSING else f.default_factory()
                 for f in fields(Spec)}


MAX_RANGE = 10_000  # values an 'a..b' range may expand to


def _int_list(value, key: str) -> list[int]:
    if isinstance(value, str):  # "3..10"
        lo, sep, hi = value.partition("..")
        if sep and lo.strip().isdigit() and hi.strip().isdigit():
            lo, hi = int(lo), int(hi)
            if lo > hi:
                raise SpecError(f"{key}: empty range {value!r} (the first number must not "
                                "exceed the last)")
            if hi - lo + 1 > MAX_RANGE:
                raise SpecError(f"{key}: range {value!r} has {hi - lo + 1} values, more than "
                                f"the {MAX_RANGE} allowed")
            return list(range(lo, hi + 1))
        raise SpecError(f"{key}: expected a list of integers or 'a..b', got {value!r}")
    if isinstance(value, int) and not isinstance(value, bool):
        return [value]
    if not isinstance(value, (list, tuple)) or not value or not all(
            isinstance(v, int) and not isinstance(v, bool) for v in value):
        raise SpecError(f"{key}: expected a non-empty list of integers, got {value!r}")
    _no_repeats(value, key)
    return list(value)


def _no_repeats(values, key: str) -> None:
    """A value listed twice would make the same cell twice."""
    seen = set()
    for v in values:
        if v in seen:
            raise SpecError(f"{key}: {v!r} is listed twice")
        seen.add(v)


def _kind(value) -> str:
    """How a spec file's reader would name the type of `value`."""
    names = {list: "a list", tuple: "a list", str: "a string", int: "a number",
             float: "a number", bool: "a boolean", type(None): "null"}
    return names.get(type(value), type(value).__name__)


def _check_k(method: str, k: int) -> None:
    m = METHODS[method]
    if not m.min_k <= k <= MAX_K:
        raise SpecError(f"K = {k} is out of range for {method}: it takes K in {m.min_k}..{MAX_K}")


def make_spec(data: dict, base_dir: Path | None = None, check_files: bool = True) -> Spec:
    """A validated Spec from a dict (as read from TOML or JSON)."""
    if not isinstance(data, dict):
        raise SpecError(f"a spec must be a table (TOML) or an object (JSON) of settings, "
                        f"got {_kind(data)}")
    unknown = sorted(set(data) - set(SPEC_DEFAULTS))
    if unknown:
        raise SpecError(f"unknown spec key(s) {', '.join(unknown)}; known keys: "
                        f"{', '.join(SPEC_DEFAULTS)}")
    d = {**{k: v for k, v in SPEC_DEFAULTS.items()}, **data}
    scenes = d["scenes"]
    if isinstance(scenes, str):
        scenes = [scenes]
    if not isinstance(scenes, list) or not scenes or not all(isinstance(s, str) and s
                                                             for s in scenes):
        raise SpecError("scenes: give at least one scene (a generated scene name, a shared "
                        "mesh name, or a .ply/.obj/.blend file)")
    _no_repeats(scenes, "scenes")
    if base_dir is not None:  # relative files are relative to the spec file
        scenes = [str(base_dir / s) if _looks_like_file(s) and not Path(s).is_absolute()
                  else s for s in scenes]
    if check_files:
        for s in scenes:
            check_scene(s)
    methods = d["methods"]
    if isinstance(methods, str):
        methods = [methods]
    if not isinstance(methods, list) or not methods or not all(isinstance(m, str)
                                                               for m in methods):
        raise SpecError("methods: give a list of method names")
    _no_repeats(methods, "methods")
    for m in methods:
        if m not in METHODS:
            raise SpecError(f"unknown method {m!r}; known methods: {', '.join(METHODS)}")
    ks = _int_list(d["ks"], "ks")
    method_ks = {}
    if not isinstance(d["method_ks"], dict):
        raise SpecError("method_ks: expected a table of method = [K, ...]")
    for m, v in d["method_ks"].items():
        if m not in METHODS:
            raise SpecError(f"method_ks: unknown method {m!r}")
        method_ks[m] = _int_list(v, f"method_ks.{m}")
    for m in methods:
        if "k" in METHODS[m].params:
            for k in method_ks.get(m, ks):
                _check_k(m, k)
    seeds = _int_list(d["seeds"], "seeds")
    if any(not 0 <= s <= 2**63 - 1 for s in seeds):
        raise SpecError(f"seeds must be in 0..{2**63 - 1}, got {seeds!r}")
    workloads = d["workloads"]
    if isinstance(workloads, str):
        workloads = [workloads]
    if (not isinstance(workloads, list) or not workloads
            or any(not isinstance(w, str) or w not in WORKLOADS for w in workloads)):
        raise SpecError(f"workloads: expected some of {', '.join(WORKLOADS)}, got {workloads!r}")
    _no_repeats(workloads, "workloads")
    for key in ("name", "scheduler"):
        if not isinstance(d[key], str):
            raise SpecError(f"{key} must be a string, got {_kind(d[key])} {d[key]!r}")
    if not d["name"] or any(c in d["name"] for c in "/\\") or d["name"].startswith("."):
        raise SpecError(f"name must be a plain file name (not empty, no '/' or '\\', not "
                        f"starting with '.'), got {d['name']!r}")

    def integer(key, lo, hi):
        v = d[key]
        if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
            raise SpecError(f"{key} must be an integer in {lo}..{hi}, got {v!r}")
        return v

    ao_distance = d["ao_distance"]
    if (isinstance(ao_distance, bool) or not isinstance(ao_distance, (int, float))
            or not 0 < ao_distance <= 10):
        raise SpecError(f"ao_distance must be a number in (0, 10], got {ao_distance!r}")
    if not isinstance(d["executor"], str) or d["executor"] not in EXECUTORS:
        raise SpecError(f"executor must be one of {', '.join(EXECUTORS)}, got {d['executor']!r}")
    if not isinstance(d["options"], dict):
        raise SpecError("options: expected a table of build options")
    spec = Spec(name=str(d["name"]), scenes=list(scenes), methods=list(methods), ks=ks,
                method_ks=method_ks, seeds=seeds,
                repetitions=integer("repetitions", 1, 1000), workloads=list(workloads),
                width=integer("width", 1, 8192), height=integer("height", 1, 8192),
                ao_samples=integer("ao_samples", 1, 64), ao_distance=float(ao_distance),
                options=dict(d["options"]), build_threads=integer("build_threads", 0, 1024),
                executor=d["executor"], workers=integer("workers", 1, 1024),
                scheduler=str(d["scheduler"]))
    _check_options(spec)
    return spec


def _check_options(spec: Spec) -> None:
    """Build options are checked by the core's own checks, per method."""
    from . import checks
    for m in spec.methods:
        allowed = set(METHODS[m].params)
        opts = {k: v for k, v in spec.options.items() if k in allowed}
        unknown = set(spec.options) - set().union(*(set(METHODS[x].params) for x in spec.methods))
        if unknown:
            raise SpecError(f"options: unknown build option(s) {', '.join(sorted(unknown))}")
        try:
            checks.build_options(METHODS[m], opts)
        except (TypeError, ValueError) as e:
            raise SpecError(f"options for {m}: {e}") from None


def load_spec(path, **overrides) -> Spec:
    """Reads a TOML (.toml) or JSON (.json) spec file; `overrides` replace keys."""
    path = Path(path)
    if path.is_dir():
        raise SpecError(f"spec file {path} is a directory")
    if not path.is_file():
        raise SpecError(f"spec file {path} does not exist")
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as e:
        raise SpecError(f"{path}: not a text (UTF-8) file: byte {e.start} is "
                        f"{e.object[e.start:e.start + 1]!r}") from None
    if path.suffix == ".json":
        try:
            data = json.loads(text)
        except json.JSONDecodeError as e:
            raise SpecError(f"{path}: not valid JSON: {e}") from None
    else:
        try:
            import tomllib
        except ImportError:  # Python 3.10
            raise SpecError("TOML specs need Python 3.11 or later; use a .json spec") from None
        try:
            data = tomllib.loads(text)
        except tomllib.TOMLDecodeError as e:
            raise SpecError(f"{path}: not valid TOML: {e}") from None
    if not isinstance(data, dict):
        raise SpecError(f"{path}: a spec must be a JSON object of settings ({{\"scenes\": "
                        f"[...], ...}}), got {_kind(data)}")
    given = {k: v for k, v in overrides.items() if v is not None}
    data.update(given)
    try:
        return make_spec(data, base_dir=path.parent)
    except SpecError as e:
        where = f"{path} with --{', --'.join(given)}" if given else str(path)
        raise SpecError(f"{where}: {e}") from None


def _looks_like_file(scene: str) -> bool:
    return Path(scene).suffix.lower() in (".ply", ".obj", ".blend") or "/" in scene


def check_scene(scene: str) -> None:
    from . import scenes, workloads
    if scene in scenes.NAMES:
        return
    if _looks_like_file(scene):
        p = Path(scene)
        if p.is_dir():
            raise SpecError(f"scene file {scene} is a directory, not a mesh file")
        if not p.is_file():
            raise SpecError(f"scene file {scene} does not exist")
        if p.suffix.lower() not in (".ply", ".obj", ".blend"):
            raise SpecError(f"scene file {scene}: expected .ply, .obj or .blend")
        return
    d = workloads.shared_scenes_dir()
    if d is None or not (d / f"{scene}.ply").exists():
        raise SpecError(f"no scene {scene!r}: not a generated scene ({', '.join(scenes.NAMES)}), "
                        f"a file, or a mesh in the shared scenes folder ({d or 'not found'})")


# -----------------------------------------------------------------------------
# Cells


@dataclass(frozen=True)
class Cell:
    scene: str
    method: str
    k: int | None
    seed: int

    @property
    def key(self) -> str:
        return f"{self.scene}|{self.method}|{'' if self.k is None else self.k}|{self.seed}"

    def label(self) -> str:
        k = "" if self.k is None else f" K={self.k}"
        return f"{Path(self.scene).name} {self.method}{k} seed {self.seed}"


def cells(spec: Spec) -> list[Cell]:
    out = []
    for scene in spec.scenes:
        for method in spec.methods:
            for k in spec.ks_of(method):
                for seed in spec.seeds_of(method):
                    out.append(Cell(scene, method, k, seed))
    return out


@dataclass
class SceneData:
    """Triangles and the camera of a scene (its own, or one framing it)."""
    triangles: np.ndarray
    camera: object


_scene_cache: dict = {}


def load_scene(scene: str) -> SceneData:
    """Loads a scene once per process."""
    if scene not in _scene_cache:
        from . import io, scenes, workloads
        from .bench import load
        camera = None
        if Path(scene).suffix.lower() == ".blend":
            tris, camera = io.load_blend(scene)
        else:
            tris = load(scene)
            if scene in scenes.NAMES:
                camera = scenes.default_camera(scene)
        _scene_cache.clear()  # one scene at a time: the big ones are 10 MB+
        _scene_cache[scene] = SceneData(tris, camera or workloads.framing_camera(tris))
    return _scene_cache[scene]


def make_rays(spec: Spec, data: SceneData, embree) -> dict:
    """The workloads' rays: {name: (origins, directions, tmax)}."""
    from . import build, workloads
    o, d = data.camera.rays(spec.width, spec.height)
    out = {"primary": (o, d, np.inf)}
    if {"ao", "diffuse"} & set(spec.workloads):
        # Secondary rays start at the primary hits; Embree's answer is the
        # reference, so every tree gets the same rays.
        hits = embree.intersect(o, d) if embree else build(data.triangles).intersect(o, d)
        lo, hi = workloads.bounds(data.triangles)
        so, sd = workloads.ambient_occlusion_rays(data.triangles, o, d, hits,
                                                  samples=spec.ao_samples)
        # AO: short rays (any occluder within reach); diffuse: a full bounce.
        out["ao"] = (so, sd, float(spec.ao_distance * np.linalg.norm(hi - lo)))
        out["diffuse"] = (so, sd, np.inf)
    return {w: out[w] for w in spec.workloads}


_kd_cache: dict = {}


def _build_options(spec: Spec, method: str, k=None, seed=None) -> dict:
    opts = {key: v for key, v in spec.options.items() if key in METHODS[method].params}
    if k is not None:
        opts["k"] = k
    if seed is not None and "seed" in METHODS[method].params:
        opts["seed"] = seed
    return opts


def kd_reference(spec: Spec, scene: str, data: SceneData):
    """The kd-tree every cell of a scene is timed against, built once per process."""
    from . import build
    key = (scene, id(data.triangles), json.dumps(_build_options(spec, "kd"), sort_keys=True))
    if key not in _kd_cache:
        _kd_cache.clear()
        _kd_cache[key] = build(data.triangles, method="kd", threads=spec.build_threads,
                               **_build_options(spec, "kd"))
    return _kd_cache[key]


def run_cell(spec: Spec, cell: Cell, scene_data: SceneData | None = None,
             progress=None) -> list[dict]:
    """Builds the cell's tree and traces every workload; one row per workload.

    Every repetition traces the cell's tree, the scene's kd-tree and Embree
    on the same rays, in a rotating order: each time has its kd and Embree
    partner measured within a fraction of a second of it, which cancels
    most of a shared machine's drift (that drift hits our memory-bound
    traversals harder than Embree's, so kd is the closer partner)."""
    from . import Cancelled, build, oracle
    data = scene_data or load_scene(cell.scene)
    tris = data.triangles
    # Not inside a Blender whose own Embree clashes with embreex's.
    usable = oracle.available() and oracle.foreign_embree_library() is None
    embree = oracle.EmbreeTracer(tris) if usable else None
    rays = make_rays(spec, data, embree)
    tree = build(tris, method=cell.method, threads=spec.build_threads, progress=progress,
                 **_build_options(spec, cell.method, cell.k, cell.seed))
    kd = tree if cell.method == "kd" else kd_reference(spec, cell.scene, data)
    s = tree.stats
    rows = []
    for w, (o, d, tmax) in rays.items():
        etmax = None if np.isinf(tmax) else tmax
        ref = embree.intersect(o, d, tmax=etmax) if embree else None
        tracers = {"ours": lambda: tree.intersect(o, d, tmax=tmax, threads=1)}
        if kd is not tree:  # the kd cell's own times are its kd times
            tracers["kd"] = lambda: kd.intersect(o, d, tmax=tmax, threads=1)
        if embree:
            tracers["embree"] = lambda: embree.intersect(o, d, tmax=etmax)
        names = list(tracers)
        times: dict[str, list] = {name: [] for name in ("ours", "kd", "embree")}
        for rep in range(spec.repetitions):
            for name in names[rep % len(names):] + names[:rep % len(names)]:
                start = time.perf_counter()
                result = tracers[name]()
                elapsed = time.perf_counter() - start
                times[name].append(embree.last_seconds if name == "embree" else elapsed)
                if name == "ours":
                    hits = result
            if progress is not None and progress.cancelled:
                raise Cancelled("cancelled")
        if kd is tree:
            times["kd"] = times["ours"]
        unexplained = grazing = ""
        if ref is not None:
            c = oracle.compare(hits, ref, triangles=tris, origins=o, directions=d)
            unexplained, grazing = len(c["unexplained"]), c["grazing"]
        rows.append({
            "scene": cell.scene, "triangles": len(tris), "method": cell.method,
            "k": "" if cell.k is None else cell.k, "seed": cell.seed, "workload": w,
            "rays": len(o), "build_s": s["build_seconds"], "nodes": s["nodes"],
            "kd_nodes": s["kd_nodes"], "general_nodes": s["general_nodes"],
            "leaves": s["leaves"], "refs_per_tri": s["duplication"], "bytes": s["bytes"],
            "sah": s["sah_cost"],
            "level_planes": " ".join(map(str, s["level_planes"])),
            "level_directions": " ".join(map(str, s["level_directions"])),
            "trace_s": " ".join(f"{x:.6g}" for x in times["ours"]),
            "kd_s": " ".join(f"{x:.6g}" for x in times["kd"]),
            "embree_s": " ".join(f"{x:.6g}" for x in times["embree"]),
            "steps": float(hits["steps"].mean()),
            "general_steps": float(hits["general_steps"].mean()),
            "tests": float(hits["tests"].mean()),
            "hits": int((hits["prim"] >= 0).sum()),
            "unexplained": unexplained, "grazing": grazing,
            "embree_build_s": embree.build_seconds if embree else "",
        })
    return rows


# -----------------------------------------------------------------------------
# Results files


def machine_info() -> dict:
    cpu = platform.processor()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    versions = {"python": platform.python_version(), "numpy": np.__version__}
    from . import __version__
    versions["bsplab"] = __version__
    try:
        from importlib.metadata import version
        versions["embreex"] = version("embreex")
    except Exception:
        versions["embreex"] = None
    return {"host": platform.node(), "machine": platform.machine(), "cpu": cpu,
            "cores": os.cpu_count(), "system": platform.platform(), "versions": versions}


class ResultsFile:
    """Rows in `<out>.csv`, the run's record in `<out>.json`; resumable."""

    def __init__(self, out, spec: Spec, fresh: bool = False):
        out = Path(out)
        self.csv = out.with_suffix(".csv")
        self.meta = out.with_suffix(".json")
        self.spec = spec
        self.rows: list[dict] = []
        self.csv.parent.mkdir(parents=True, exist_ok=True)
        if fresh:
            self.csv.unlink(missing_ok=True)
            self.meta.unlink(missing_ok=True)
        if self.csv.exists() and self.meta.exists():
            meta = json.loads(self.meta.read_text())
            if meta.get("fingerprint") != spec.fingerprint():
                raise SpecError(f"{self.csv} holds results of a different spec; pass --fresh "
                                "to start over or choose another --out")
            with open(self.csv, newline="") as f:
                rows = list(csv.DictReader(f))
            # A run killed mid-write leaves a cut last line or a cell with some
            # of its workloads: drop those rows, the cell runs again.
            self.rows = [r for r in rows if all(r.get(k) is not None for k in ROW_FIELDS)]
            complete = self.done()
            self.rows = [r for r in self.rows if self._key(r) in complete]
            if len(self.rows) != len(rows):
                self._rewrite()
        else:
            self.csv.unlink(missing_ok=True)
        self._start_run()
        if not self.csv.exists():
            with open(self.csv, "w", newline="") as f:
                csv.DictWriter(f, fieldnames=ROW_FIELDS).writeheader()

    def _meta(self) -> dict:
        return json.loads(self.meta.read_text()) if self.meta.exists() else {}

    def _start_run(self) -> None:
        meta = self._meta()
        meta.update({"fingerprint": self.spec.fingerprint(), "spec": asdict(self.spec)})
        # Every (re)start of the run is recorded: a resumed run may have
        # continued on another machine.
        meta.setdefault("runs", []).append({
            "started": time.strftime("%Y-%m-%d %H:%M:%S"), "command": " ".join(sys.argv),
            "cells_before": len(self.done()), "machine": machine_info()})
        self.meta.write_text(json.dumps(meta, indent=2))

    def finish(self, seconds: float) -> None:
        meta = self._meta()
        meta["runs"][-1].update(finished=time.strftime("%Y-%m-%d %H:%M:%S"),
                                seconds=round(seconds, 3), cells_after=len(self.done()))
        self.meta.write_text(json.dumps(meta, indent=2))

    @staticmethod
    def _key(r: dict) -> str:
        return Cell(r["scene"], r["method"], int(r["k"]) if r["k"] else None, int(r["seed"])).key

    def _rewrite(self) -> None:
        with open(self.csv, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=ROW_FIELDS)
            w.writeheader()
            w.writerows(self.rows)

    def done(self) -> set[str]:
        have: dict[str, set] = {}
        for r in self.rows:
            have.setdefault(self._key(r), set()).add(r["workload"])
        return {k for k, ws in have.items() if ws >= set(self.spec.workloads)}

    def add(self, rows: list[dict]) -> None:
        with open(self.csv, "a", newline="") as f:
            csv.DictWriter(f, fieldnames=ROW_FIELDS).writerows(rows)
        self.rows += [{k: str(v) for k, v in r.items()} for r in rows]


# -----------------------------------------------------------------------------
# Running


class ProgressBar:
    """One line on the terminal: cells done, the current cell, time left."""

    def __init__(self, total: int, stream=None, width: int = 28):
        self.total, self.done, self.width = total, 0, width
        self.stream = stream or sys.stderr
        self.start = time.perf_counter()
        self.tty = self.stream.isatty()

    def update(self, done: int, label: str) -> None:
        self.done = done
        frac = done / self.total if self.total else 1.0
        elapsed = time.perf_counter() - self.start
        eta = elapsed / done * (self.total - done) if done else 0.0
        bar = "#" * int(frac * self.width) + "." * (self.width - int(frac * self.width))
        line = (f"[{bar}] {done}/{self.total} cells {elapsed:5.0f}s elapsed"
                f"{f', ~{eta:.0f}s left' if done else ''}  {label}")
        if self.tty:
            self.stream.write("\r" + line[:160].ljust(160))
        else:
            self.stream.write(line + "\n")
        self.stream.flush()

    def close(self) -> None:
        if self.tty:
            self.stream.write("\n")
            self.stream.flush()


def run(spec: Spec, out, *, fresh: bool = False, executor=None,
        on_progress: Callable[[int, int, str], None] | None = None,
        scene_data: dict | None = None, progress=None, quiet: bool = False) -> list[dict]:
    """Runs every cell not yet in `out`; returns all rows (old and new).

    `scene_data` maps scene names to in-memory SceneData (the add-on's
    scene), which forces the inline executor. `progress` (a bsplab.Progress)
    lets another thread cancel between and inside cells."""
    from . import executors
    results = ResultsFile(out, spec, fresh=fresh)
    finished = results.done()
    todo = [c for c in cells(spec) if c.key not in finished]
    total = len(cells(spec))
    done = total - len(todo)
    bar = None if quiet else ProgressBar(total)
    if bar:
        bar.update(done, f"{done} cells already in {results.csv}" if done else "starting")
    if executor is None:
        executor = executors.make(spec, inline=scene_data is not None)
    start = time.perf_counter()
    try:
        for cell, rows in executor.map(spec, todo, scene_data=scene_data, progress=progress):
            results.add(rows)
            done += 1
            if bar:
                bar.update(done, cell.label())
            if on_progress:
                on_progress(done, total, cell.label())
    finally:
        if bar:
            bar.close()
        executor.close()
    results.finish(time.perf_counter() - start)
    return results.rows


# The columns `report` reads, and how each must parse. Others (and the
# kd_s column that older runs lack) are optional.
REPORT_COLUMNS = {
    "scene": "text", "workload": "text", "method": "text", "k": "int?", "triangles": "int",
    "rays": "int", "build_s": "number", "kd_nodes": "number", "general_nodes": "number",
    "bytes": "number", "steps": "number", "tests": "number", "unexplained": "int?",
    "level_planes": "ints", "level_directions": "ints", "trace_s": "numbers",
    "embree_s": "numbers?",
}


def _parses(value: str, kind: str) -> bool:
    if kind == "text":
        return True
    if value.strip() == "":  # '?' kinds may be empty, and so may a tree's level lists
        return kind.endswith("?") or kind == "ints"
    convert = int if kind.startswith("int") else float
    try:
        for x in value.split():
            convert(x)
    except ValueError:
        return False
    return kind.rstrip("?") in ("ints", "numbers") or len(value.split()) == 1


def read_rows(path) -> list[dict]:
    """The rows of an `experiment` results file (`path`, or `path` with a
    .csv suffix); ValueError naming the file when it is not one."""
    if Path(path).is_dir():
        raise ValueError(f"{path} is a directory, not a results file (give the .csv "
                         "`experiment` wrote)")
    csv_path = Path(path).with_suffix(".csv")
    if csv_path.is_dir():
        raise ValueError(f"{csv_path} is a directory, not a results file")
    if not csv_path.is_file():
        raise FileNotFoundError(f"no results file {csv_path}")
    try:
        with open(csv_path, newline="", encoding="utf-8") as f:
            reader = csv.DictReader(f)
            rows = list(reader)
            columns = reader.fieldnames or []
    except (UnicodeDecodeError, csv.Error) as e:
        raise ValueError(f"{csv_path}: not a CSV results file ({e})") from None
    missing = [c for c in REPORT_COLUMNS if c not in columns]
    if missing:
        raise ValueError(f"{csv_path}: not the results of `python -m bsplab experiment`: "
                         f"missing column(s) {', '.join(missing)}")
    for i, r in enumerate(rows, start=2):
        if None in r.values():
            raise ValueError(f"{csv_path}: line {i} has too few columns (a run cut short? "
                             "rerun the experiment with the same spec to complete it)")
        for c, kind in REPORT_COLUMNS.items():
            if not _parses(r[c], kind):
                raise ValueError(f"{csv_path}: line {i}: column {c} has {r[c]!r}, expected "
                                 f"{_EXPECTED[kind]}")
    if not rows:
        raise ValueError(f"{csv_path}: no result rows (only the header)")
    return rows


_EXPECTED = {"text": "text", "int": "a whole number", "int?": "a whole number or nothing",
             "number": "a number", "ints": "whole numbers separated by spaces",
             "numbers": "numbers separated by spaces",
             "numbers?": "numbers separated by spaces, or nothing"}


def iter_times(value: str) -> Iterable[float]:
    return (float(x) for x in value.split()) if value else ()
