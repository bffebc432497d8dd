"""Experiment specs: the settings of a run (scenes x methods x K x seeds x
option variants, the workloads, repetitions), read from TOML or JSON and
checked up front, so that a long run never stops on a typo."""

from __future__ import annotations

import hashlib
import json
import re
from dataclasses import MISSING, asdict, dataclass, field, fields
from pathlib import Path

from .. import scenes as scene_names
from ..method_table import MAX_K, METHODS

WORKLOADS = ("primary", "ao", "diffuse", "random")
EXECUTORS = ("process", "dask", "inline")

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
    workers: int = 1              # parallel trials (more than 1 disturbs the timings)
    scheduler: str = ""           # dask: a running scheduler's address; "": local cluster
    # Keys the benchmarks brought (left out of the fingerprint at their
    # defaults, so older results files still resume):
    variants: list = field(default_factory=lambda: [{}])  # option tables crossed with trials
    method_variants: dict = field(default_factory=dict)   # per-method variants replacing them
    random_rays: int = 65_536     # rays of the `random` workload
    cull: bool = False            # also trace each tree with leaf culling on, paired
    hits_only: bool = False       # also trace each tree on its hits-only paths, paired
    # How a scene's instances are built: "flat" (one tree over the flattened
    # triangles, the theses' setting) or "two-level" (a tree per mesh and a
    # BVH over the instances, bsplab.build_instanced; a flat scene is then
    # one mesh under one identity instance). Instanced worlds are the scenes
    # "instanced:<name>" of bsplab.instanced_scenes.WORLDS.
    instances: str = "flat"

    def fingerprint(self) -> str:
        """What decides the rows (not how they are run): resume only matches this."""
        d = asdict(self)
        for k in ("executor", "workers", "scheduler", "name", "build_threads"):
            d.pop(k)
        for k in LATER_KEYS:
            if d[k] == SPEC_DEFAULTS[k]:
                d.pop(k)
        return hashlib.sha1(json.dumps(d, sort_keys=True).encode()).hexdigest()[:12]

    def ks_of(self, method: str) -> list:
        if "k" not in METHODS[method].params:
            return [None]
        return list(self.method_ks.get(method, self.ks))

    def seeds_of(self, method: str) -> list:
        return list(self.seeds) if "seed" in METHODS[method].params else [self.seeds[0]]

    def variants_of(self, method: str) -> list[str]:
        """The method's option variants, each as its canonical JSON text."""
        return [variant_key(v) for v in self.method_variants.get(method, self.variants)]


def variant_key(options: dict) -> str:
    """A variant's canonical text ("" for no options): trial keys and rows hold it."""
    return json.dumps(options, sort_keys=True) if options else ""


def variant_label(key: str) -> str:
    """`intersect_cost 0.3, leaf_boxes clipped` (or `defaults`) for tables."""
    options = json.loads(key) if key else {}
    return ", ".join(f"{k} {v}" for k, v in options.items()) or "defaults"


LATER_KEYS = ("variants", "method_variants", "random_rays", "cull", "hits_only", "instances")
INSTANCES = ("flat", "two-level")
INSTANCED_PREFIX = "instanced:"
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
    """A value listed twice would make the same trial twice."""
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
    _check_depth(data)
    d = {**{k: v for k, v in SPEC_DEFAULTS.items()}, **data}
    scenes = _name_list(d, "scenes")
    if not isinstance(scenes, list) or not scenes or not all(isinstance(s, str) and s
                                                             for s in scenes):
        raise SpecError("scenes: give at least one scene (a generated scene name, a shared "
                        "mesh name, or a .ply/.obj/.blend file)")
    _no_repeats(scenes, "scenes")
    if base_dir is not None:  # relative files are relative to the spec file
        scenes = [str(base_dir / s)
                  if scene_names.looks_like_file(s) and not Path(s).is_absolute() else s
                  for s in scenes]
    if check_files:
        for s in scenes:
            check_scene(s)
    methods = _name_list(d, "methods")
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
    with_k = [m for m in methods if "k" in METHODS[m].params]
    for m, v in d["method_ks"].items():
        _check_method_key("method_ks", m, methods)
        if m not in with_k:
            raise SpecError(f"method_ks: {m} takes no K; the spec's methods that take K: "
                            f"{', '.join(with_k) or 'none'}")
        method_ks[m] = _int_list(v, f"method_ks.{m}")
    for m in methods:
        if "k" in METHODS[m].params:
            for k in method_ks.get(m, ks):
                _check_k(m, k)
    seeds = _int_list(d["seeds"], "seeds")
    if any(not 0 <= s <= 2**63 - 1 for s in seeds):
        raise SpecError(f"seeds must be in 0..{2**63 - 1}, got {seeds!r}")
    workloads = _name_list(d, "workloads")
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
    _check_scheduler(d["scheduler"], d["executor"])
    if not isinstance(d["options"], dict):
        raise SpecError("options: expected a table of build options")
    variants = _variants(d["variants"], "variants")
    if not isinstance(d["method_variants"], dict):
        raise SpecError("method_variants: expected a table of method = [{options}, ...]")
    method_variants = {}
    for m, v in d["method_variants"].items():
        _check_method_key("method_variants", m, methods)
        method_variants[m] = _variants(v, f"method_variants.{m}")
    for key in ("cull", "hits_only"):
        if not isinstance(d[key], bool):
            raise SpecError(f"{key} must be true or false, got {_kind(d[key])} {d[key]!r}")
    if not isinstance(d["instances"], str) or d["instances"] not in INSTANCES:
        raise SpecError(f"instances must be one of {', '.join(map(repr, INSTANCES))}, "
                        f"got {d['instances']!r}")
    if d["instances"] == "two-level" and d["cull"]:
        raise SpecError("cull = true: leaf culling is not offered for two-level scenes "
                        "(instances = \"two-level\"); use instances = \"flat\" to time culling")
    spec = Spec(name=str(d["name"]), scenes=list(scenes), methods=list(methods), ks=ks,
                method_ks=method_ks, seeds=seeds,
                repetitions=integer("repetitions", 1, 1000), workloads=list(workloads),
                width=integer("width", 1, 8192), height=integer("height", 1, 8192),
                ao_samples=integer("ao_samples", 1, 64), ao_distance=float(ao_distance),
                options=dict(d["options"]), build_threads=integer("build_threads", 0, 1024),
                executor=d["executor"], workers=integer("workers", 1, 1024),
                scheduler=str(d["scheduler"]), variants=variants,
                method_variants=method_variants,
                random_rays=integer("random_rays", 1, 100_000_000), cull=d["cull"],
                hits_only=d["hits_only"], instances=d["instances"])
    _check_options(spec)
    return spec


def _name_list(d: dict, key: str):
    """The list of names under `key`; a bare string is refused, as it may
    mean one name or a typo'd list and the spec says which only with [...]."""
    value = d[key]
    if isinstance(value, str):
        raise SpecError(f"{key} must be a list of names, got a string {value!r} (write "
                        f"{key} = [{json.dumps(value)}])")
    return value


def _check_method_key(key: str, method: str, methods: list) -> None:
    """A per-method table's key must be one of the spec's methods."""
    if method not in METHODS:
        raise SpecError(f"{key}: unknown method {method!r}; the spec's methods: "
                        f"{', '.join(methods)}")
    if method not in methods:
        raise SpecError(f"{key}: {method} is not among the spec's methods "
                        f"({', '.join(methods)}); it would be ignored")


# A Dask scheduler address: [protocol://]host:port.
_ADDRESS = re.compile(r"((tcp|tls|ws|wss)://)?(\[[0-9a-fA-F:]+\]|[A-Za-z0-9._-]+):(\d{1,5})")


def _check_scheduler(scheduler, executor: str) -> None:
    if not isinstance(scheduler, str) or not scheduler:
        return  # its type is checked with the other strings
    if executor != "dask":
        raise SpecError(f"scheduler {scheduler!r} is only for executor = \"dask\" (executor "
                        f"is {executor!r}); remove it or set executor = \"dask\"")
    m = _ADDRESS.fullmatch(scheduler)
    if m is None or not 1 <= int(m.group(4)) <= 65535:
        raise SpecError(f"scheduler must be a Dask scheduler address such as "
                        f"tcp://host:8786 (protocol tcp, tls, ws or wss; port 1..65535), got "
                        f"{scheduler!r}")


# How deeply a spec's tables and lists may nest: the deepest a spec needs
# is method_variants -> method -> list -> option table -> value.
MAX_DEPTH = 8


def _check_depth(data: dict) -> None:
    """Refuses tables or lists nested beyond MAX_DEPTH (walked without
    recursion, so any depth is measured)."""
    stack = [(data, 1, "")]
    while stack:
        value, depth, where = stack.pop()
        if depth > MAX_DEPTH:
            raise SpecError(f"nested too deeply: {where.lstrip('.')} lies {depth} tables or "
                            f"lists deep; a spec needs at most {MAX_DEPTH}")
        items = (value.items() if isinstance(value, dict) else
                 enumerate(value) if isinstance(value, list) else ())
        for k, v in items:
            if isinstance(v, (dict, list)):
                stack.append((v, depth + 1, f"{where}.{k}" if isinstance(k, str)
                              else f"{where}[{k}]"))


def _variants(value, key: str) -> list[dict]:
    if (not isinstance(value, list) or not value
            or not all(isinstance(v, dict) for v in value)):
        raise SpecError(f"{key}: expected a non-empty list of option tables, got {value!r}")
    _no_repeats([variant_key(v) for v in value], key)
    return [dict(v) for v in value]


def _check_options(spec: Spec) -> None:
    """Build options are checked by the library's own checks (bsplab.checks), per method and variant."""
    from .. import checks
    known = set().union(*(set(METHODS[x].params) for x in spec.methods))
    for m in spec.methods:
        for variant in spec.method_variants.get(m, spec.variants):
            given = {**spec.options, **variant}
            unknown = set(given) - known
            if unknown:
                raise SpecError(f"options: unknown build option(s) {', '.join(sorted(unknown))}")
            opts = {k: v for k, v in given.items() if k in METHODS[m].params}
            try:
                checks.build_options(METHODS[m], opts)
            except (TypeError, ValueError) as e:
                raise SpecError(f"options for {m}: {e}") from None


def build_options(spec: Spec, method: str, k=None, seed=None, variant: str = "") -> dict:
    """The options `bsplab.build` gets for one trial: the spec's, the variant's,
    K and the seed, each kept only where the method takes it."""
    given = {**spec.options, **(json.loads(variant) if variant else {})}
    opts = {key: v for key, v in given.items() if key in METHODS[method].params}
    if k is not None:
        opts["k"] = k
    if seed is not None and "seed" in METHODS[method].params:
        opts["seed"] = seed
    return opts


def load_spec(path, **overrides) -> Spec:
    """Reads a TOML (.toml) or JSON (.json) spec file; `overrides` replace keys."""
    path = Path(path)
    if path.is_dir():
        raise SpecError(f"spec file {path} is a directory")
    if path.exists() and not path.is_file():  # a FIFO or a device: never opened
        raise SpecError(f"spec file {path} is not a regular file")
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
        except RecursionError:
            raise _too_deep(path) from None
    else:
        try:
            import tomllib
        except ImportError:  # Python 3.10
            raise SpecError("TOML specs need Python 3.11 or later; use a .json spec") from None
        try:
            data = tomllib.loads(text)
        except tomllib.TOMLDecodeError as e:
            raise SpecError(f"{path}: not valid TOML: {e}") from None
        except RecursionError:
            raise _too_deep(path) from None
    if not isinstance(data, dict):
        raise SpecError(f"{path}: a spec must be a JSON object of settings ({{\"scenes\": "
                        f"[...], ...}}), got {_kind(data)}")
    given = {k: v for k, v in overrides.items() if v is not None}
    if "methods" in given:  # the file's per-method tables, narrowed to the methods given
        for key in ("method_ks", "method_variants"):
            if isinstance(data.get(key), dict):
                data[key] = {m: v for m, v in data[key].items() if m in given["methods"]}
    data.update(given)
    try:
        return make_spec(data, base_dir=path.parent)
    except SpecError as e:
        where = f"{path} with --{', --'.join(given)}" if given else str(path)
        raise SpecError(f"{where}: {e}") from None


def _too_deep(path: Path) -> SpecError:
    return SpecError(f"{path}: nested too deeply: its tables or lists lie inside each other "
                     f"beyond what the reader can follow (a spec needs at most {MAX_DEPTH} "
                     "levels)")


def check_scene(scene: str) -> None:
    """SpecError unless `scene` names a generated scene, a mesh file or a shared
    mesh (checked before the run, so the messages name the spec's mistake)."""
    if scene in scene_names.NAMES + scene_names.PROBE_NAMES:
        return
    if scene.startswith(INSTANCED_PREFIX):
        from ..instanced_scenes import WORLDS
        if scene[len(INSTANCED_PREFIX):] not in WORLDS:
            raise SpecError(f"unknown instanced world {scene!r}; worlds: "
                            f"{', '.join(INSTANCED_PREFIX + w for w in WORLDS)}")
        return
    if scene_names.looks_like_file(scene):
        p = Path(scene)
        if p.is_dir():
            raise SpecError(f"scene file {scene} is a directory, not a mesh file")
        if p.exists() and not p.is_file():
            raise SpecError(f"scene file {scene} is not a regular file")
        if not p.is_file():
            raise SpecError(f"scene file {scene} does not exist")
        if p.suffix.lower() not in scene_names.FILE_SUFFIXES:
            raise SpecError(f"scene file {scene}: expected .ply, .obj or .blend")
        return
    try:
        scene_names.shared_path(scene)
    except FileNotFoundError as e:
        raise SpecError(str(e)) from None
