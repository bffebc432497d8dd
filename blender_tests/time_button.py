"""Button-to-preview time in Blender: the add-on's Build & Render pressed on a
shared mesh, timed from the press to the image block written.

    blender_tests/time_button.sh [-- --scene conference --preview 50 --presses 5 --cold]

Blender's own PLY importer reads /work/shared/scenes/<scene>.ply (or
$BSPLAB_SHARED_SCENES), a camera frames it as the lab's primary rays do
(`bsplab.workloads.framing_camera`), render resolution 1920 x 1080 at
--preview percent, no Embree comparison. The first press builds the tree
and renders the preview (shaded); before each further press only the
shading mode changes (normal, shaded, normal, ...), so those presses re-use
the tree (docs/addon.md). With --cold the kept tree is forgotten before
every press, so every press builds (as on a new scene). The script prints
every press's wall time and the panel's build/fingerprint/render times, then
the first press and the median of the others. Runs on the bpy module
(time_button.sh sets it up like the demo) or a Blender binary:
    BSPLAB_PYTHONPATH=build/blender-deps blender -b --factory-startup \\
        --python blender_tests/time_button.py -- --scene conference
"""

import argparse
import os
import pathlib
import statistics
import sys
import time

import bpy

REPO = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "addon/tools"))
import demo_headless  # noqa: E402  (the add-on loader)


def script_argv():
    """The script's arguments: those after Blender's "--", else the command
    line's (the bpy module runs it as a plain Python script)."""
    return sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:]


def add_core_paths():
    """Make `bsplab` importable from BSPLAB_PYTHONPATH (a Blender binary's
    Python ignores PYTHONPATH)."""
    for entry in reversed(os.environ.get("BSPLAB_PYTHONPATH", "").split(os.pathsep)):
        if entry and entry not in sys.path:
            sys.path.insert(0, entry)


def ready_addon(scene, method, preview, k=None, quality=None):
    """The add-on loaded and registered once, and the scene's Build & Render
    set as every timing script presses it: `method` (with K `k` when given,
    else the method's own), shaded, `preview` percent of the render size, no
    Embree comparison, the build quality `quality` when given (else the
    panel's default). Returns (add-on module, the scene's settings)."""
    addon = demo_headless.load_addon()
    if not hasattr(bpy.types.Scene, "bsplab"):
        addon.register()
    settings = scene.bsplab
    settings.method, settings.render_mode = method, "shaded"
    settings.preview_percentage, settings.compare_with_embree = preview, False
    if k is not None:
        settings.k = k
    if quality is not None:
        settings.build_quality = quality
    return addon, settings


def run(main):
    """Exit with main()'s code; the bpy module leaves by os._exit, as it can
    crash in its static destructors at exit."""
    code = main()
    sys.stdout.flush()
    if not bpy.app.binary_path:
        os._exit(code)
    sys.exit(code)


def scene_arguments(prog):
    """A parser with the options the timing scripts share (this one and
    time_inspector.py): the shared scene, the preview percentage, the method."""
    p = argparse.ArgumentParser(prog=prog)
    p.add_argument("--scene", default="conference")
    p.add_argument("--preview", type=int, default=50)
    p.add_argument("--method", default="kd")
    p.add_argument("--k", type=int, help="K of the methods that take one (default: the method's)")
    p.add_argument("--quality", choices=("exact", "fast"),
                   help="the build quality (default: the panel's, fast)")
    return p


def parse_args():
    p = scene_arguments("time_button.py")
    p.add_argument("--presses", type=int, default=5)
    p.add_argument("--no-counts", action="store_true",
                   help="Count Steps & Tests off: the preview traced in packets")
    p.add_argument("--cold", action="store_true",
                   help="forget the kept tree before every press: every press builds")
    return p.parse_args(script_argv())


def import_scene(path):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    if hasattr(bpy.ops.wm, "ply_import"):
        bpy.ops.wm.ply_import(filepath=str(path))
    else:  # Blender 3.x: the legacy Python importer
        bpy.ops.import_mesh.ply(filepath=str(path))
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = 1920, 1080
    return scene


def add_camera(scene, triangles):
    import bsplab.workloads
    cam = bsplab.workloads.framing_camera(triangles)
    data = bpy.data.cameras.new("Camera")
    data.lens, data.sensor_width, data.sensor_height = cam.lens, cam.sensor_width, cam.sensor_height
    data.clip_start, data.clip_end = 1e-4, 1e6
    obj = bpy.data.objects.new("Camera", data)
    scene.collection.objects.link(obj)
    import mathutils
    obj.matrix_world = mathutils.Matrix([list(row) for row in cam.matrix_world])
    scene.camera = obj
    bpy.context.view_layer.update()


def main():
    args = parse_args()
    add_core_paths()
    import bsplab
    from bsplab import io, workloads
    shared = workloads.shared_scenes_dir()
    if shared is None:
        print("time_button: no shared scenes folder", file=sys.stderr)
        return 2
    path = shared / f"{args.scene}.ply"
    scene = import_scene(path)
    add_camera(scene, io.load_mesh(path))
    addon, settings = ready_addon(scene, args.method, args.preview, args.k, args.quality)
    if hasattr(settings, "count_steps"):
        settings.count_steps = not args.no_counts
    print(f"time_button: Blender {bpy.app.version_string}, {args.scene}, {args.method}"
          f"{f' K={settings.k}' if hasattr(settings, 'k') and args.k else ''}, "
          f"{getattr(settings, 'build_quality', 'exact')}, "
          f"{args.preview}% of 1920x1080, kernels {bsplab.cpu_features()['selected']}, "
          f"counts {'off' if args.no_counts else 'on'}")
    walls = [press_button(addon, settings, press, args.cold) for press in range(args.presses)]
    print(f"time_button: first press {walls[0]:.3f} s", end="")
    if len(walls) > 1:
        print(f"; presses 2-{len(walls)} ({'cold' if args.cold else 'shading changed'}): "
              f"median {statistics.median(walls[1:]):.3f} s", end="")
    print()
    return 0


# Before each press after the first: only the shading mode changes.
SHADING_CYCLE = ("normal", "shaded")


def press_button(addon, settings, press, cold):
    """Press Build & Render once; print and return its wall time."""
    if press == 0 or cold:
        addon.state.STATE.forget_trees()
    if press > 0:
        settings.render_mode = SHADING_CYCLE[(press - 1) % len(SHADING_CYCLE)]
    start = time.perf_counter()
    bpy.ops.bsplab.build_render()
    wall = time.perf_counter() - start
    stats = settings.stats
    build = stats["build"]
    tree = "tree reused" if build.get("reused") else "tree built"
    print(f"  press {press + 1} ({settings.render_mode}): {wall:.3f} s  {tree}  "
          f"(panel: build {build['build_seconds']:.3f} s, "
          f"fingerprint {1e3 * (build.get('fingerprint_seconds') or 0):.1f} ms, "
          f"render {stats['render']['seconds']:.3f} s)", flush=True)
    return wall


if __name__ == "__main__":
    run(main)
