# SPDX-License-Identifier: GPL-3.0-or-later
"""The ray inspector on a two-level build (a bsplab.InstancedTree), without
bpy: the walk of InstancedTree.trace_path as the panel lists it and the
arrays the viewport draws of it.

trace_path replays the core's walk: the top level's node visits (boxes, in
world units), then, at each top leaf, the instances whose mesh tree the ray
entered, each with its mesh tree's own trace_path of the ray carried to the
instance's object space. That ray is o' + t d' = A^-1 (o + t d - b): the same
t as the world ray, so every t range reads in world distances.

The inspection has the keys of trace.inspect()'s (so the panel's totals and
the draw handler work alike), with "structure" "two_level",
"mesh_structure" (of the mesh trees: "bsp" or "bvh"), "top_rows" (one per
top node visited) and "visits" (one per instance entered: its instance,
mesh, whether it holds the hit, and trace.step_rows of its walk).
"""

import numpy as np

from ..drawing import boxes
from . import trace, walk_arrays

# The top-level boxes the ray entered are drawn in one colour, apart from the
# visit ramp of the cells inside the instances (walk_arrays.FIRST_CELL ..
# LAST_CELL), so the two levels never read alike.
TOP_BOX_COLOUR = np.array((1.0, 0.65, 0.2, 0.55), np.float32)


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


def counts(path):
    """The walk's totals: trace.counts' (summed over the instances entered)
    and the top level's, the hit's instance and mesh."""
    hit = int(path["instance"]) >= 0 and np.isfinite(path["t"])
    visits = path["instances"]
    leaves = sum(int(np.count_nonzero(v["path"]["kind"] == trace.LEAF)) for v in visits)
    hit_visit = next((v for v in visits if v["instance"] == path["instance"]), None)
    out = trace.totals(path, hit, leaves)
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


def segment_end(tree, path, origin):
    """How far to draw the ray: to the hit, else to where it leaves the last
    top box it entered, else (it missed the scene's box) past the box, as
    trace.segment_end does for one tree."""
    if int(path["instance"]) >= 0 and np.isfinite(path["t"]):
        return float(path["t"])
    if len(path["top"]["t_range"]):
        return float(np.max(path["top"]["t_range"][:, 1]))
    lo, hi = scene_box(tree)
    return float(np.linalg.norm((lo + hi) / 2 - origin) + np.linalg.norm(hi - lo))


def inspect(tree, origin, direction, source, names=((), ())):
    """Trace one ray through both levels of `tree` and keep what the panel
    and the viewport show (see the module's docstring). `names` are the
    build's (instance names, mesh names), for the panel."""
    origin = np.asarray(origin, dtype=np.float32)
    direction = np.asarray(direction, dtype=np.float32)
    path = tree.trace_path(origin, direction)
    hit_instance = int(path["instance"])
    visits = [{"instance": int(v["instance"]), "mesh": int(v["mesh"]),
               "hit": int(v["instance"]) == hit_instance,
               "rows": trace.step_rows(v["path"])} for v in path["instances"]]
    return {
        "source": source,
        "structure": "two_level",
        "mesh_structure": getattr(tree.meshes[0], "structure", "bsp") if tree.meshes else "bsp",
        "origin": origin,
        "direction": direction,
        "cull": False,  # no leaf culling in two levels (InstancedTree.intersect refuses it)
        "path": path,
        "counts": counts(path),
        "top_rows": top_rows(tree, path),
        "visits": visits,
        # The inner steps one after the other, as the flat inspection's rows.
        "rows": [row for visit in visits for row in visit["rows"]],
        "names": names,
        "missed_box": int(path["top_steps"]) == 0,
        "end_t": segment_end(tree, path, origin.astype(np.float64)),
    }


def instance_cells(tree, visit):
    """(2E, 3) world line-list vertices of what the ray crossed inside one
    instance entered (`visit`, a trace_path "instances" entry): the cells of
    the leaves it visited, or, in a BVH mesh tree, the boxes of the nodes it
    entered (carried to the world as 8 corners: a rotated box stays a box)."""
    instance, inner = int(visit["instance"]), visit["path"]
    if getattr(tree.meshes[int(visit["mesh"])], "structure", "bsp") == "bvh":
        lo, hi = trace.entered_boxes(inner)
        world = tree.to_world(instance, boxes.corners(lo, hi))
        return boxes.corner_segments(world)
    segments = []
    for leaf in inner["node"][inner["kind"] == trace.LEAF].tolist():
        cell = tree.instance_leaf_cells(instance, max_depth=0, root=int(leaf))
        segments.append(cell["vertices"][cell["edges"].reshape(-1)])
    if not segments:
        return np.zeros((0, 3), np.float32)
    return np.concatenate(segments).astype(np.float32)


def draw_data(tree, inspection):
    """walk_arrays.draw_data()'s arrays for a two-level walk: "ray", "hit";
    "cell_coords" / "cell_colours" the top-level boxes entered (first
    "top_vertices" rows, TOP_BOX_COLOUR) then, instance by instance, the
    cells (or boxes) crossed inside (one colour per instance, on the visit
    ramp);
    "tri_coords" / "tri_colours" the tested triangles in world units. Also
    "instance_cells": per instance entered, (instance, its cell vertices).
    """
    path = inspection["path"]
    hit_instance = inspection["counts"]["hit_instance"]
    ray, hit = walk_arrays.ray_segment(inspection, hit_instance is not None)

    top = boxes.segments(path["top"]["box_lo"], path["top"]["box_hi"])
    per_instance = [(int(v["instance"]), instance_cells(tree, v)) for v in path["instances"]]
    inner = [coords for _, coords in per_instance]
    # One colour per instance entered, on the visit ramp in the order the
    # ray entered them: which cells belong to which instance reads at once.
    cell_counts = [len(c) for c in inner]
    ramp = walk_arrays.visit_colours(len(inner))
    inner_colours = [np.broadcast_to(colour, (count, 4)) for colour, count in
                     zip(ramp, cell_counts)]
    cell_coords = np.concatenate([top] + inner) if inner else top
    cell_colours = np.concatenate([np.broadcast_to(TOP_BOX_COLOUR, (len(top), 4))]
                                  + inner_colours)

    tris, colours = [], []
    for visit in path["instances"]:
        instance = int(visit["instance"])
        hit_prim = int(path["prim"]) if instance == hit_instance else None
        prims, cols = walk_arrays.tested_triangle_colours(visit["path"], hit_prim)
        mesh = tree.meshes[int(visit["mesh"])]
        local = mesh.triangles[prims.astype(np.int64)]
        tris.append(tree.to_world(instance, local).reshape(-1, 3))
        colours.append(np.repeat(cols, 3, axis=0))
    return {
        "ray": ray,
        "hit": hit,
        "cell_coords": np.ascontiguousarray(cell_coords, dtype=np.float32),
        "cell_colours": np.ascontiguousarray(cell_colours, dtype=np.float32),
        "tri_coords": np.ascontiguousarray(np.concatenate(tris) if tris else
                                           np.zeros((0, 3)), dtype=np.float32),
        "tri_colours": np.ascontiguousarray(np.concatenate(colours) if colours else
                                            np.zeros((0, 4)), dtype=np.float32),
        "top_vertices": len(top),
        "instance_cells": per_instance,
    }
