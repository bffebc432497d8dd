"""Click-to-panel time of the ray inspector on a shared scene.

    blender_tests/time_button.sh is the set-up this borrows: Blender's PLY
    importer reads /work/shared/scenes/<scene>.ply (or $BSPLAB_SHARED_SCENES),
    a camera frames it (bsplab.workloads.framing_camera), 1920 x 1080 at
    --preview percent. One Build & Render, then --picks preview pixels on a
    grid over the render, each through bpy.ops.bsplab.inspect_pixel as the
    panel's eyedropper calls it: the time from the call to the kept
    inspection (trace_path, the step rows, the viewport arrays) is what a
    click costs before the panel redraws. Prints the median and the largest,
    and the shares of trace_path and of the drawing arrays.

    PYTHONPATH=build/blender-deps .venv-bpy42/bin/python \\
        blender_tests/time_inspector.py -- --scene conference
    BSPLAB_PYTHONPATH=build/blender-deps blender -b --factory-startup \\
        --python blender_tests/time_inspector.py -- --scene conference

Exits 0 with a note (not a failure) when the shared scenes are missing.
"""

import os
import statistics
import sys
import time

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import bsplab_test_utils as utils  # noqa: E402
import time_button  # noqa: E402  (the scene and camera set-up, the add-on loader)


def parse_args():
    p = time_button.scene_arguments("time_inspector.py")
    p.add_argument("--picks", type=int, default=50)
    return p.parse_args(time_button.script_argv())


def grid_pixels(width, height, count):
    """About `count` pixels spread over a width x height render (x, row)."""
    side = max(1, int(round(count ** 0.5)))
    return [(int((i + 0.5) * width / side), int((j + 0.5) * height / side))
            for j in range(side) for i in range(side)]


def ms(seconds):
    return 1000.0 * seconds


def main():
    args = parse_args()
    utils.add_core_paths()
    from bsplab import io, workloads
    shared = workloads.shared_scenes_dir()
    path = None if shared is None else shared / f"{args.scene}.ply"
    if path is None or not path.exists():
        print(f"time_inspector: no shared scene {args.scene!r}: nothing timed")
        return 0
    scene = time_button.import_scene(path)
    time_button.add_camera(scene, io.load_mesh(path))
    addon, settings = time_button.ready_addon(scene, args.method, args.preview, args.k,
                                              args.quality)
    settings.instances = "flatten"  # a shared mesh is one object: nothing to instance
    assert bpy.ops.bsplab.build_render() == {'FINISHED'}
    build = addon.state.STATE.shown_build
    tree = build.tree()
    width, height = build.render_size
    image_h = build.image_size[1]
    print(f"time_inspector: Blender {bpy.app.version_string}, {args.scene} "
          f"({tree.stats['triangles']} triangles, {tree.stats['nodes']} nodes), {args.method}, "
          f"preview {width} x {height}")
    walls, kept, traces, drawing, steps, hits = [], [], [], [], [], 0
    for x, row in grid_pixels(width, height, args.picks):
        start = time.perf_counter()
        assert bpy.ops.bsplab.inspect_pixel(x=x, y=image_h - 1 - row) == {'FINISHED'}
        walls.append(time.perf_counter() - start)
        inspection = addon.state.STATE.inspection
        kept.append(inspection["seconds"])
        steps.append(inspection["counts"]["steps"])
        hits += inspection["counts"]["hit_prim"] is not None
        # The parts, again on the same ray: the walk, then the arrays.
        start = time.perf_counter()
        tree.trace_path(inspection["origin"], inspection["direction"], cull=build.cull)
        traces.append(time.perf_counter() - start)
        start = time.perf_counter()
        addon.inspector.draw.draw_data(tree, build.triangles, inspection)
        drawing.append(time.perf_counter() - start)
    print(f"time_inspector: {len(walls)} picks ({hits} hits, median {statistics.median(steps)} "
          f"steps, at most {max(steps)})")
    print(f"time_inspector: operator call (click to panel ready): median "
          f"{ms(statistics.median(walls)):.1f} ms, largest {ms(max(walls)):.1f} ms")
    print(f"time_inspector: inside the operator: median {ms(statistics.median(kept)):.1f} ms; "
          f"trace_path {ms(statistics.median(traces)):.2f} ms, drawing arrays "
          f"{ms(statistics.median(drawing)):.2f} ms (medians)")
    return 0


if __name__ == "__main__":
    code = main()
    sys.stdout.flush()
    os._exit(code)  # the bpy 4.2 module may crash in its static destructors
