# SPDX-License-Identifier: GPL-3.0-or-later
"""The ray inspector's ray and its walk, without bpy.

A pick in the preview becomes the very ray Build & Render traced for that
pixel (`pixel_ray`, the camera model of `bsplab.Camera.rays` restated for one
pixel: the Blender tests check it bit for bit against `rays()`), a pick in
the viewport a ray from the view. `inspect()` traces it with the kept tree's
`trace_path` and turns the walk into what the panel lists: the counts and
one row per visited node (for a BVH, the boxes the ray entered);
`inspect_two_level()` does the same for a two-level build's walk through
both levels. operators.py chooses between them by `tree.structure`.
"""

import numpy as np

from ..jobs.worker import UserError

# Names of the trace_path codes (bsplab.tree.KINDS / TEST_RESULTS), restated
# here so that the panel draws without the core.
KINDS = ("x", "y", "z", "leaf", "general", "box")
TEST_RESULTS = ("miss", "hit", "culled", "seen")
LEAF = KINDS.index("leaf")
BOX = KINDS.index("box")  # a BVH's interior node (its leaves are LEAF)
MISS, HIT, CULLED, SEEN = range(4)


def pixel_ray(cam, width, height, x, row):
    """(origin, direction) float32 of pixel (x, row) of a `width` x `height`
    render of `cam` (a bsplab.Camera), row 0 at the top: the same numbers
    `cam.rays(width, height)` gives at index row * width + x, computed for
    this one pixel instead of all of them (the same float64 steps in the same
    order, so the same float32 ray)."""
    xmin, xmax, ymin, ymax = cam.viewplane(width, height)
    local = np.empty((1, 3))
    local[0, 0] = xmin + (x + 0.5) * ((xmax - xmin) / width)
    local[0, 1] = ymax - (row + 0.5) * ((ymax - ymin) / height)
    local[0, 2] = -1.0
    # As rays(): Blender ignores the object's scale for the view.
    axes = cam.matrix_world[:3, :3] / np.linalg.norm(cam.matrix_world[:3, :3], axis=0)
    direction = local @ axes.T
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    return cam.matrix_world[:3, 3].astype(np.float32), direction[0].astype(np.float32)


def render_pixel(x, y, image_size, render_size):
    """The render's (column, row from the top) under pixel (x, y) of the
    preview image, counted as Blender counts image pixels (x from the left,
    y from the bottom row). The render sits at the image's top left; a heat
    preview has its colour bar below it (legend.with_heat_bar). Raises
    UserError for a pixel off the image or off the render."""
    image_w, image_h = image_size
    render_w, render_h = render_size
    if not (0 <= x < image_w and 0 <= y < image_h):
        raise UserError("Pixel ({}, {}) is outside the preview image ({} x {} pixels)".format(
            x, y, image_w, image_h))
    row = image_h - 1 - y
    if x >= render_w or row >= render_h:
        raise UserError("Pixel ({}, {}) is on the colour bar, not on the render: the render is "
                        "the top left {} x {} pixels of the preview".format(
                            x, y, render_w, render_h))
    return x, row


def plane_text(kind, plane):
    """How the panel shows a node's split plane (n.p = d): "x = 0.5" for a
    kd node, "(0.60,0.80,0.00)p = 2" for a general one, "" for a leaf and
    for a BVH's box node (it has no plane)."""
    if kind in (LEAF, BOX):
        return ""
    n, d = plane[:3], plane[3]
    if kind < LEAF:  # an axis plane: n is the axis itself
        return "{} = {:.3g}".format(KINDS[kind], d)
    return "({:.2f},{:.2f},{:.2f})p = {:.3g}".format(n[0], n[1], n[2], d)


def step_rows(path):
    """One row per visited node, in visit order: (number from 1, kind name,
    plane text, t0, t1, tests, culled) - tests and culled are the leaf's
    triangle references tested and skipped by culling (0 for interior nodes;
    references this ray already tested in an earlier leaf count in neither)."""
    steps = len(path["node"])
    results, owners = path["test_result"], path["test_step"].astype(np.int64)
    tested = np.bincount(owners[(results == MISS) | (results == HIT)], minlength=steps)
    culled = np.bincount(owners[results == CULLED], minlength=steps)
    return [(i + 1, KINDS[kind], plane_text(kind, path["plane"][i]),
             float(path["t_range"][i][0]), float(path["t_range"][i][1]),
             int(tested[i]), int(culled[i]))
            for i, kind in enumerate(path["kind"].tolist())]


def counts(path):
    """The walk's totals as the panel shows them."""
    hit = int(path["prim"]) >= 0 and np.isfinite(path["t"])
    return totals(path, hit, int(np.count_nonzero(path["kind"] == LEAF)))


def totals(path, hit, leaves):
    """The counters of a walk's path (flat, or a two-level walk's summed
    over the instances entered), the hit (when `hit`) and `leaves`."""
    return {
        "steps": int(path["steps"]),
        "general_steps": int(path["general_steps"]),
        "tests": int(path["tests"]),
        "culled": int(path["culled"]),
        # Ray-box tests: a BVH's counter (0 on kd and BSP trees, and absent
        # from the paths of a core before BVHs).
        "box_tests": int(path.get("box_tests", 0)),
        "hit_prim": int(path["prim"]) if hit else None,
        "hit_t": float(path["t"]) if hit else None,
        "leaves": leaves,
    }


def entered_boxes(path):
    """The boxes of a BVH's visited nodes in visit order, (lo, hi) (S, 3)
    each; empty for a kd or BSP tree's walk (its rows are NaN)."""
    lo = np.asarray(path.get("box_lo", np.zeros((0, 3))), np.float64).reshape(-1, 3)
    hi = np.asarray(path.get("box_hi", np.zeros((0, 3))), np.float64).reshape(-1, 3)
    keep = np.isfinite(lo).all(axis=1) & np.isfinite(hi).all(axis=1)
    return lo[keep], hi[keep]


def segment_end(path, box_bounds, origin):
    """How far to draw the ray: to the hit, else to where it leaves the tree's
    box, else (it missed the box) as far as the box is from the origin plus
    its diagonal, so the ray still shows passing the box by."""
    if int(path["prim"]) >= 0 and np.isfinite(path["t"]):
        return float(path["t"])
    if len(path["t_range"]):
        return float(np.max(path["t_range"][:, 1]))
    lo, hi = (np.asarray(c, dtype=np.float64) for c in box_bounds)
    centre = (lo + hi) / 2
    return float(np.linalg.norm(centre - origin) + np.linalg.norm(hi - lo))


def inspect(tree, origin, direction, cull, source):
    """Trace one ray with `tree` and keep what the panel and the viewport
    show: a plain dict. `source` says where the ray came from (for the
    panel: e.g. "pixel (12, 40)" or "viewport")."""
    origin = np.asarray(origin, dtype=np.float32)
    direction = np.asarray(direction, dtype=np.float32)
    path = tree.trace_path(origin, direction, cull=bool(cull))
    total = counts(path)
    return {
        "source": source,
        # "bvh" or "bsp" (split planes): which counters and drawing apply.
        "structure": tree.structure,
        "origin": origin,
        "direction": direction,
        "cull": bool(cull),
        "path": path,
        "counts": total,
        "rows": step_rows(path),
        "missed_box": len(path["node"]) == 0,
        "end_t": segment_end(path, tree.bounds, origin.astype(np.float64)),
    }


# -- a two-level build's walk (a bsplab.InstancedTree) ---------------------------


def top_rows(tree, path):
    """One row per top-level node visited, in visit order: (number from 1,
    "box" or "leaf", t0, t1, the leaf's instances (a tuple; () for a box))."""
    top = path["top"]
    arrays = tree.top_boxes()
    # top_boxes lists every node once; find each visited node's row.
    where = {int(n): i for i, n in enumerate(arrays["node"].tolist())}
    rows = []
    for k, node in enumerate(top["node"].tolist()):
        row = where[int(node)]
        leaf = bool(arrays["leaf"][row])
        rows.append((k + 1, "leaf" if leaf else "box", float(top["t_range"][k][0]),
                     float(top["t_range"][k][1]),
                     tuple(int(i) for i in arrays["instances"][row]) if leaf else ()))
    return rows


def two_level_counts(path):
    """The walk's totals: counts' (summed over the instances entered)
    and the top level's, the hit's instance and mesh."""
    hit = int(path["instance"]) >= 0 and np.isfinite(path["t"])
    visits = path["instances"]
    leaves = sum(int(np.count_nonzero(v["path"]["kind"] == LEAF)) for v in visits)
    hit_visit = next((v for v in visits if v["instance"] == path["instance"]), None)
    out = totals(path, hit, leaves)
    out.update({
        "top_steps": int(path["top_steps"]),
        "instance_visits": int(path["instance_visits"]),
        "hit_instance": int(path["instance"]) if hit else None,
        "hit_mesh": int(hit_visit["mesh"]) if hit and hit_visit is not None else None,
        "flat_prim": int(path["flat_prim"]) if hit else None,
    })
    return out


def scene_box(tree):
    """(lo, hi) of the top level's root box: the whole scene."""
    root = tree.top_boxes(0)
    if not len(root["node"]):
        return np.zeros(3), np.zeros(3)
    return root["lo"][0].astype(np.float64), root["hi"][0].astype(np.float64)


def two_level_segment_end(tree, path, origin):
    """How far to draw the ray: to the hit, else to where it leaves the last
    top box it entered, else (it missed the scene's box) past the box, as
    segment_end does for one tree."""
    if int(path["instance"]) >= 0 and np.isfinite(path["t"]):
        return float(path["t"])
    if len(path["top"]["t_range"]):
        return float(np.max(path["top"]["t_range"][:, 1]))
    lo, hi = scene_box(tree)
    return float(np.linalg.norm((lo + hi) / 2 - origin) + np.linalg.norm(hi - lo))


def inspect_two_level(tree, origin, direction, source, names=((), ())):
    """Trace one ray through both levels of `tree` and keep what the panel
    and the viewport show. `names` are the build's (instance names, mesh
    names), for the panel.

    InstancedTree.trace_path records the core's walk: the top level's node
    visits (boxes, in world units), then, at each top leaf, the instances
    whose mesh tree the ray entered, each with its mesh tree's own
    trace_path of the ray carried to the instance's object space. That ray
    is o' + t d' = A^-1 (o + t d - b): the same t as the world ray, so every
    t range reads in world distances.

    The inspection has inspect()'s keys (so the panel's totals and the draw
    handler work alike), with "structure" "two_level", "mesh_structure" (of
    the mesh trees: "bsp" or "bvh"), "top_rows" (one per top node visited)
    and "visits" (one per instance entered: its instance, mesh, whether it
    holds the hit, and step_rows of its walk)."""
    origin = np.asarray(origin, dtype=np.float32)
    direction = np.asarray(direction, dtype=np.float32)
    path = tree.trace_path(origin, direction)
    hit_instance = int(path["instance"])
    visits = [{"instance": int(v["instance"]), "mesh": int(v["mesh"]),
               "hit": int(v["instance"]) == hit_instance,
               "rows": step_rows(v["path"])} for v in path["instances"]]
    return {
        "source": source,
        "structure": tree.structure,
        "mesh_structure": tree.meshes[0].structure if tree.meshes else None,
        "origin": origin,
        "direction": direction,
        "cull": False,  # no leaf culling in two levels (InstancedTree.intersect refuses it)
        "path": path,
        "counts": two_level_counts(path),
        "top_rows": top_rows(tree, path),
        "visits": visits,
        # The inner steps one after the other, as the flat inspection's rows.
        "rows": [row for visit in visits for row in visit["rows"]],
        "names": names,
        "missed_box": int(path["top_steps"]) == 0,
        "end_t": two_level_segment_end(tree, path, origin.astype(np.float64)),
    }
