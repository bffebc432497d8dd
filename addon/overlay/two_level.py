# SPDX-License-Identifier: GPL-3.0-or-later
"""The tree overlay of a two-level build (a bsplab.InstancedTree), as plain
numpy arrays (no bpy, no gpu): the top level's boxes and, for the instance
under the 3D cursor, that instance's own mesh tree drawn in place.

The arrays have the keys of geometry.overlay_geometry(), so the draw handler
makes the same three batches of them: the instance's split planes are the
"TRIS" faces and their outlines, the top level's boxes are more "LINES"
over the same positions (appended after the planes' vertices), and the
instance's cells (or, for a BVH mesh tree, its node boxes) are the cell
wireframe. Everything comes from the InstancedTree's own queries
(top_boxes, instance_at, instance_split_polygons, instance_leaf_cells,
instance_node_boxes), which already carry the instance's geometry to the
world; this module only colours and packs it.

The settings keep their flat meaning, applied to each level: "Depth" is how
deep both the top level's boxes and the instance's tree are drawn, "Colour"
colours the instance's planes (kind: the kind the plane has in the mesh's
own tree, which a rotated instance turns in the world), "Cells" adds the
instance's cells, "Scope" draws the instance's whole tree or only its
subtree under the cursor, "Most Polygons" caps every part.
"""

import numpy as np

from .. import backend
# The one test of "two-level", shared with Build & Render (geometry.py asks it here).
from ..build_render.tree_cache import is_two_level
from ..drawing import boxes
from . import geometry

# The top level's boxes are thin outlines under the instance's tree: the
# depth ramp's colours at this alpha, so the instance drawn in place stands
# out from the boxes around it.
TOP_BOX_ALPHA = 0.6
# Said when the cursor is in no instance's mesh box.
NO_INSTANCE_NOTE = "3D cursor is over no instance: place it inside one to draw its tree"


def instance_under(tree, cursor):
    """The instance whose mesh box holds `cursor` (InstancedTree.instance_at:
    the smallest such box), or None (also for no cursor)."""
    if cursor is None:
        return None
    found = tree.instance_at(cursor)
    # instance_at says None; a core that answers -1 means the same.
    return None if found is None or int(found) < 0 else int(found)


def object_point(tree, instance, point):
    """A world point in `instance`'s object space (where its mesh tree
    lives), by the core's inverse, as instance_at carried it."""
    return tree.to_object(instance, point)


def top_geometry(tree, settings):
    """The top level's boxes down to settings.max_depth (cut at settings.cap,
    shallow levels first: top_boxes lists them level by level) as a wireframe
    coloured by depth: (positions (8B, 3), colours (8B, 4), edges (12B, 2),
    the top_boxes dict of the drawn boxes, how many there are in all)."""
    found = tree.top_boxes(settings.max_depth)
    total = len(found["node"])
    keep = slice(0, min(total, settings.cap))
    found = {key: value[keep] for key, value in found.items()}
    positions, edges = boxes.wireframe(found["lo"], found["hi"])
    rgb = np.repeat(geometry.depth_colours(found["depth"], settings.max_depth), 8, axis=0)
    colours = np.hstack([rgb, np.full((len(rgb), 1), TOP_BOX_ALPHA, np.float32)])
    return positions, colours.astype(np.float32), edges, found, total


def _instance_root(mesh_tree, settings, local_cursor):
    """(node, depth) of the instance's tree the overlay starts from (the
    flat overlay's subtree_root, with the cursor in object space)."""
    return geometry.subtree_root(mesh_tree, settings, local_cursor)


def _instance_planes(tree, instance, settings, root):
    """The instance's split polygons in the world, capped as the flat overlay's."""
    return geometry._capped_walk(lambda depth, node, cap: tree.instance_split_polygons(
        instance, depth, root=node, max_polygons=cap), settings, root)


def _instance_boxes(tree, instance, settings, root):
    """A BVH mesh tree's node boxes of the instance, as world corners."""
    return geometry._capped_walk(lambda depth, node, cap: tree.instance_node_boxes(
        instance, depth, root=node, max_boxes=cap), settings, root)


def two_level_geometry(tree, settings, cursor=None):
    """The overlay's arrays for a two-level build `tree` (the keys of
    geometry.overlay_geometry(), "polygons" counting the instance's split
    polygons - or node boxes - and "top_boxes" the top level's boxes drawn),
    plus "two_level" True, "instance" (the index drawn in place, or None),
    "mesh" (its mesh), "top_total" and, per drawn top box, "top_depth" and
    "top_node"; "instance_cells" (the instance's cells' world vertices, for
    the tests: they lie inside its world box)."""
    bsplab = backend.import_bsplab()
    top_positions, top_colours, top_edges, top, top_total = top_geometry(tree, settings)
    top_note = geometry.count_note(len(top["node"]), len(top["node"]) < top_total, top_total,
                                   False, settings.cap, "top-level boxes")
    instance = instance_under(tree, cursor)
    out = geometry.empty_geometry(top_note)
    out.update({"two_level": True, "instance": instance, "mesh": None,
                "top_boxes": len(top["node"]), "top_total": top_total,
                "top_depth": top["depth"], "top_node": top["node"],
                "instance_cells": np.zeros((0, 3), np.float32)})
    # The instance's part first (its polygon fan indices start at 0), then
    # the top boxes' corners after them in the same position array.
    positions = np.zeros((0, 3), np.float32)
    colours = np.zeros((0, 4), np.float32)
    outline_colours = np.zeros((0, 4), np.float32)
    face_indices = np.zeros((0, 3), np.uint32)
    line_indices = np.zeros((0, 2), np.uint32)
    if instance is None:
        out["notes"].append(NO_INSTANCE_NOTE if cursor is not None else
                            "no 3D cursor: no instance drawn in place")
    else:
        mesh = int(tree.mesh_index[instance])
        mesh_tree = tree.meshes[mesh]
        out["mesh"] = mesh
        local = object_point(tree, instance, cursor)
        start = _instance_root(mesh_tree, settings, local)
        if start is None:
            # instance_at found the point inside the mesh's box; a BVH's
            # node_at may still find no leaf box holding it.
            out["notes"].append("3D cursor is in no leaf box of the instance's tree")
        elif geometry.is_bvh(mesh_tree):
            root, root_depth = start
            found, total, total_cut = _instance_boxes(tree, instance, settings, root)
            positions, line_indices = boxes.corner_wireframe(found["corners"])
            rgb = np.repeat(geometry.depth_colours(found["depth"], settings.max_depth), 8, axis=0)
            colours = np.hstack([rgb, np.full((len(rgb), 1), settings.alpha, np.float32)])
            outline_colours = np.hstack(
                [rgb, np.full((len(rgb), 1), geometry.OUTLINE_ALPHA, np.float32)])
            shown = len(found["node"])
            out.update({"polygons": shown, "polygon_total": total, "cut": bool(found["cut"]),
                        "boxes": shown, "root": int(root), "root_depth": int(root_depth),
                        "depth": found["depth"], "node": found["node"],
                        "instance_cells": positions})
            out["notes"].append(geometry.count_note(shown, found["cut"], total, total_cut,
                                                    settings.cap, "node boxes of the instance"))
            out["notes"].append(geometry.BVH_NOTE)
        else:
            root, root_depth = start
            polygons, total, total_cut = _instance_planes(tree, instance, settings, root)
            rgb = geometry.polygon_colours(polygons, settings)
            positions = np.ascontiguousarray(polygons["vertices"], np.float32)
            colours = geometry.per_vertex(rgb, polygons["offsets"], settings.alpha)
            outline_colours = geometry.per_vertex(rgb, polygons["offsets"],
                                                  geometry.OUTLINE_ALPHA)
            face_indices = np.ascontiguousarray(polygons["triangles"], np.uint32)
            line_indices = bsplab.polygons.edge_pairs(polygons["offsets"])
            shown = len(polygons["node"])
            out.update({"polygons": shown, "polygon_total": total,
                        "cut": bool(polygons["cut"]), "root": int(root),
                        "root_depth": int(root_depth), "kind": polygons["kind"],
                        "depth": polygons["depth"], "node": polygons["node"]})
            out["notes"].append(geometry.count_note(shown, polygons["cut"], total, total_cut,
                                                    settings.cap,
                                                    "split polygons of the instance"))
            if settings.cells:
                cells = tree.instance_leaf_cells(instance, max_depth=settings.max_depth + 1,
                                                 root=root, max_cells=settings.cap)
                vertices = np.ascontiguousarray(cells["vertices"], np.float32)
                out.update({
                    "cell_positions": vertices,
                    "cell_colours": np.tile(np.array(geometry.CELL_COLOUR, np.float32),
                                            (len(vertices), 1)),
                    "cell_indices": np.ascontiguousarray(cells["edges"], np.uint32),
                    "cells": len(cells["node"]), "cells_cut": bool(cells["cut"]),
                    "instance_cells": vertices,
                })
                out["notes"].append("{:,} cells of the instance".format(len(cells["node"])) + (
                    " (cut at {:,})".format(settings.cap) if cells["cut"] else ""))
        if start is not None and settings.scope == "cursor":
            out["notes"].insert(1, "subtree of its node {:,} (depth {})".format(*start))
    base = len(positions)
    out.update({
        "face_positions": np.ascontiguousarray(np.vstack([positions, top_positions]),
                                               np.float32),
        "face_colours": np.ascontiguousarray(np.vstack([colours, top_colours]), np.float32),
        "face_indices": face_indices,
        "line_colours": np.ascontiguousarray(np.vstack([outline_colours, top_colours]),
                                             np.float32),
        "line_indices": np.ascontiguousarray(
            np.vstack([line_indices, top_edges + np.uint32(base)]), np.uint32),
    })
    out["cut"] = out["cut"] or len(top["node"]) < top_total
    return out
