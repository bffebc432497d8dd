"""The tracing kernels of every instruction-set level (core/src/trace/kernels/,
compiled once per level, chosen at run time by core/src/trace/cpu_dispatch.cpp).

Each level this CPU supports is forced in a subprocess with BSPLAB_ISA and
must give the same hits as the level chosen here, bit for bit, for every
method, ray family, range, counters and culling setting - so the agreement
matrix against Embree, which runs on the chosen level, holds for every
level. (The levels are the same arithmetic: -ffp-contract=off, no fused
multiply-add.)"""

from __future__ import annotations

import functools
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import bsplab

LEVELS = ("sse2", "avx2", "avx512")
SUPPORTED = bsplab.cpu_features()["supported"]

# Run in a subprocess with BSPLAB_ISA set: writes every case's hits to an .npz.
CASES_SCRIPT = r"""
import sys, json
import numpy as np
sys.path.insert(0, sys.argv[2])
import bsplab
from test_isa_levels import CASES
out = {}
for name, hits in CASES[sys.argv[3]]():
    for key, value in hits.items():
        out[name + "/" + key] = value
np.savez(sys.argv[1], **out)
print(json.dumps(bsplab.cpu_features()))
"""


@functools.lru_cache(maxsize=2)
def expected_hits(kind: str = "generated") -> dict:
    return {f"{name}/{k}": v for name, hits in CASES[kind]() for k, v in hits.items()}


def cases():
    """(name, hits) of every kernel variant on a few trees and ray families."""
    from bsplab import ray_families, scenes, workloads
    # Small scenes: every method's tree in well under a second.
    for scene in ("room", "tilted", "grids"):
        tris = scenes.generate(scene)
        parts = [ray_families.family(f, tris, 300, 5) for f in ray_families.FAMILIES]
        o, d, tmax = (np.concatenate(x) for x in zip(*parts))
        po, pd = workloads.primary_rays(tris, 48, 40)
        to, td = workloads.primary_rays(tris, 48, 40, tiles=True)
        # Random rays: the hits-only path's loop for incoherent rays.
        ro, rd = workloads.random_rays(tris, 600)
        for method in ("kd", "rbsp", "bsp_wn+kd", "bsp_cn", "bsp_ize+kd"):
            tree = bsplab.build(tris, method=method)
            for cull in (False, True):
                for counters in (False, True):
                    tag = f"{scene}/{method}/cull={cull}/counters={counters}"
                    yield tag + "/families", tree.intersect(o, d, tmax=tmax, cull=cull,
                                                            counters=counters, threads=1)
                    yield tag + "/primary", tree.intersect(po, pd, cull=cull,
                                                           counters=counters, threads=1)
                    yield tag + "/random", tree.intersect(ro, rd, cull=cull,
                                                          counters=counters, threads=1)
            # Packets: each level's own width (4, 8, 16 lanes), the same hits.
            tag = f"{scene}/{method}/packets"
            yield tag + "/families", tree.intersect(o, d, tmax=tmax, counters=False,
                                                    packets=True, threads=1)
            yield tag + "/tiles", tree.intersect(to, td, counters=False, packets=True, threads=1)
    # Leaves of up to 41 triangles, exact ties, rays through shared edges
    # (test_leaf_simd.py): each level's SIMD leaf blocks (4, 8 or 16 lanes).
    from test_leaf_simd import TREES, big_leaf_scene, lattice_rays
    o, d = lattice_rays()
    for i, options in enumerate(TREES):
        tree = bsplab.build(big_leaf_scene(), method="kd", **options)
        for cull in (False, True):
            for counters in (False, True):
                yield f"big_leaf/{i}/cull={cull}/counters={counters}", tree.intersect(
                    o, d, cull=cull, counters=counters, threads=1)


def shared_cases():
    """(name, hits) of the kernels on the real meshes: kd on every shared
    scene, a ^Kd tree with general nodes on two of them; primary rays (image
    and tile order), random rays; counters, culling and packets."""
    from bsplab import io, workloads
    for path in workloads.shared_scene_paths():
        tris = io.load_mesh(path)
        po, pd = workloads.primary_rays(tris, 160, 120)
        to, td = workloads.primary_rays(tris, 160, 120, tiles=True)
        ro, rd = workloads.random_rays(tris, 20_000, seed=3)
        methods = ("kd", "bsp_wn+kd") if path.stem in ("bunny", "sponza_dabrovic") else ("kd",)
        for method in methods:
            tree = bsplab.build(tris, method=method)
            tag = f"{path.stem}/{method}"
            for name, o, d in (("primary", po, pd), ("random", ro, rd)):
                yield f"{tag}/{name}/hits_only", tree.intersect(o, d, counters=False)
                yield f"{tag}/{name}/counted_culled", tree.intersect(o, d, cull=True)
            yield f"{tag}/tiles/packets", tree.intersect(to, td, counters=False, packets=True)


CASES = {"generated": cases, "shared": shared_cases}


def run_level(level: str, tmp_path: Path, kind: str = "generated") -> tuple[dict, dict]:
    out = tmp_path / f"{level}.npz"
    env = dict(os.environ, BSPLAB_ISA=level)
    proc = subprocess.run([sys.executable, "-c", CASES_SCRIPT, str(out),
                           str(Path(__file__).parent), kind],
                          env=env, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    features = json.loads(proc.stdout.strip().splitlines()[-1])
    with np.load(out) as data:
        return features, {k: data[k] for k in data.files}


def test_cpu_features_describe_this_process():
    f = bsplab.cpu_features()
    assert f["supported"][0] == "sse2", "every x86-64 CPU runs the baseline"
    assert all(level in LEVELS for level in f["supported"])
    assert f["selected"] in f["supported"]
    if os.environ.get("BSPLAB_ISA"):
        assert f["forced"] == f["selected"] == os.environ["BSPLAB_ISA"]
    else:
        assert f["forced"] is None and f["selected"] == f["supported"][-1]


@pytest.mark.parametrize("value, message", [("avx9000", "unknown level"), ("SSE2", "unknown level")])
def test_a_bad_level_is_a_clear_error(value, message):
    proc = subprocess.run([sys.executable, "-c", "import bsplab; bsplab.cpu_features()"],
                          env=dict(os.environ, BSPLAB_ISA=value), capture_output=True, text=True)
    assert proc.returncode != 0
    assert f"BSPLAB_ISA={value}: {message}" in proc.stderr


@pytest.mark.parametrize("level", LEVELS)
def test_every_level_gives_the_same_hits(level, tmp_path):
    if level not in SUPPORTED:
        pytest.skip(f"this CPU lacks {level} (supported: {SUPPORTED})")
    features, got = run_level(level, tmp_path)
    assert features["selected"] == level and features["forced"] == level
    expected = expected_hits()
    assert got.keys() == expected.keys()
    hits = 0
    for key, value in expected.items():
        assert np.array_equal(value.view(np.uint8), got[key].view(np.uint8)), (
            f"{level}: {key} differs on {int((value != got[key]).sum())} rays")
        hits += int((value >= 0).sum()) if key.endswith("/prim") else 0
    assert hits > 10_000  # the cases hit something


# Slow under emulation, and outside the sanitizer run (QEMU cannot host ASan's shadow memory).
@pytest.mark.slow
def test_runs_on_a_cpu_with_only_sse2(tmp_path):
    """The module's every part - builders, dispatch, the baseline kernels -
    on an emulated x86-64 CPU without AVX (QEMU's qemu64 model: SSE2, SSE3;
    it raises SIGILL on any AVX instruction): the dispatch must choose sse2,
    nothing may use a newer instruction outside the kernels of a higher level,
    and the hits must be the native ones. QEMU user mode comes from Debian's
    qemu-user (.ci/run installs it; CI fails rather than skips without it)."""
    qemu = shutil.which("qemu-x86_64")
    if qemu is None:
        if os.environ.get("CI"):
            pytest.fail("qemu-x86_64 is missing (apt-get install qemu-user)")
        pytest.skip("qemu-x86_64 not installed (apt-get install qemu-user)")
    out = tmp_path / "qemu64.npz"
    env = {k: v for k, v in os.environ.items() if k != "BSPLAB_ISA"}
    # Some machines set OPENBLAS_CORETYPE to their own CPU (e.g. Haswell, where
    # OpenBLAS's detection is unreliable); numpy's import-time dot would then run
    # AVX2 kernels on the emulated CPU and die of SIGILL before bsplab loads. The
    # emulated CPU is an SSE3 one: name OpenBLAS's kernel for it.
    if "OPENBLAS_CORETYPE" in env:
        env["OPENBLAS_CORETYPE"] = "Prescott"
    proc = subprocess.run([qemu, "-cpu", "qemu64", sys.executable, "-c", CASES_SCRIPT, str(out),
                           str(Path(__file__).parent), "generated"],
                          env=env, capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stderr[-3000:]
    features = json.loads(proc.stdout.strip().splitlines()[-1])
    assert features["supported"] == ["sse2"] and features["selected"] == "sse2"
    with np.load(out) as data:
        got = {k: data[k] for k in data.files}
    expected = expected_hits()
    assert got.keys() == expected.keys()
    for key, value in expected.items():
        assert np.array_equal(value.view(np.uint8), got[key].view(np.uint8)), key


# Outside the sanitizer run: a kd build of every shared mesh per level.
@pytest.mark.slow
@pytest.mark.parametrize("level", LEVELS)
def test_every_level_gives_the_same_hits_on_the_shared_scenes(level, tmp_path):
    """The agreement matrix against Embree runs on the level chosen here;
    every other level must give its hits bit for bit on the real meshes too."""
    from bsplab import workloads
    if not workloads.shared_scene_paths():
        pytest.skip("no shared scenes here (../shared/scenes)")
    if level not in SUPPORTED:
        pytest.skip(f"this CPU lacks {level} (supported: {SUPPORTED})")
    features, got = run_level(level, tmp_path, "shared")
    assert features["selected"] == level
    expected = expected_hits("shared")
    assert got.keys() == expected.keys()
    for key, value in expected.items():
        assert np.array_equal(value.view(np.uint8), got[key].view(np.uint8)), (
            f"{level}: {key} differs on {int((value != got[key]).sum())} rays")
