# SPDX-License-Identifier: GPL-3.0-or-later
"""The tree overlay of a two-level build (a bsplab.InstancedTree), as plain
numpy arrays (no bpy, no gpu): the top level's boxes and, for the instance
under the 3D cursor, that instance's own mesh tree drawn in place.

The instance's part is the flat overlay's own (geometry.py, chosen by the
mesh tree's structure), walked through an `InstanceView`: the
InstancedTree's queries (instance_split_polygons, instance_leaf_cells,
instance_node_boxes) under a flat tree's names, which already carry the
instance's geometry to the world. The top level's boxes (top_boxes) are
more "LINES" over the same positions, appended after the instance's.

The settings keep their flat meaning, applied to each level: "Depth" is how
deep both the top level's boxes and the instance's tree are drawn, "Colour"
colours the instance's planes (kind: the kind the plane has in the mesh's
own tree, which a rotated instance turns in the world), "Cells" adds the
instance's cells, "Scope" draws the instance's whole tree or only its
subtree under the cursor, "Most Polygons" caps every part.
"""

import numpy as np

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


class InstanceView:
    """One instance's mesh tree as the flat overlay walks it (the queries of
    geometry.TreeView), in the world."""

    of = " of the instance"
    subtree = "its node"

    def __init__(self, tree, instance):
        self.tree, self.instance = tree, instance

    def split_polygons(self, depth, root, cap):
        return self.tree.instance_split_polygons(self.instance, depth, root=root,
                                                 max_polygons=cap)

    def node_boxes(self, depth, root, cap):
        return self.tree.instance_node_boxes(self.instance, depth, root=root, max_boxes=cap)

    def leaf_cells(self, depth, root, cap):
        return self.tree.instance_leaf_cells(self.instance, max_depth=depth, root=root,
                                             max_cells=cap)

    @staticmethod
    def wireframe(found):
        # A rotated box stays a box: its 8 world corners.
        return boxes.corner_wireframe(found["corners"])


def two_level_geometry(tree, settings, cursor=None):
    """The overlay's arrays for a two-level build `tree` (the keys of
    geometry.overlay_geometry(), "polygons" counting the instance's split
    polygons - or node boxes - and "top_boxes" the top level's boxes drawn),
    plus "two_level" True, "instance" (the index drawn in place, or None),
    "mesh" (its mesh), "top_total" and, per drawn top box, "top_depth" and
    "top_node"; "instance_cells" (the instance's cells' world vertices, for
    the tests: they lie inside its world box)."""
    top_positions, top_colours, top_edges, top, top_total = top_geometry(tree, settings)
    top_note = geometry.count_note(len(top["node"]), len(top["node"]) < top_total, top_total,
                                   False, settings.cap, "top-level boxes")
    instance = instance_under(tree, cursor)
    out = instance_part(tree, instance, settings, cursor)
    out["notes"].insert(0, top_note)
    out.update({"two_level": True, "instance": instance,
                "top_boxes": len(top["node"]), "top_total": top_total,
                "top_depth": top["depth"], "top_node": top["node"]})
    # The instance's part first (its polygon fan indices start at 0), then
    # the top boxes' corners after them in the same position array.
    base = len(out["face_positions"])
    out.update({
        "face_positions": np.ascontiguousarray(
            np.vstack([out["face_positions"], top_positions]), np.float32),
        "face_colours": np.ascontiguousarray(
            np.vstack([out["face_colours"], top_colours]), np.float32),
        "line_colours": np.ascontiguousarray(
            np.vstack([out["line_colours"], top_colours]), np.float32),
        "line_indices": np.ascontiguousarray(
            np.vstack([out["line_indices"], top_edges + np.uint32(base)]), np.uint32),
    })
    out["cut"] = out["cut"] or len(top["node"]) < top_total
    return out


def instance_part(tree, instance, settings, cursor):
    """The arrays of `instance`'s mesh tree drawn in place (the flat
    overlay's, by its structure), with its "mesh" and "instance_cells"; of
    nothing, with the reason, when no instance is under the cursor."""
    if instance is None:
        out = geometry.empty_geometry(NO_INSTANCE_NOTE if cursor is not None else
                                      "no 3D cursor: no instance drawn in place")
        out.update({"mesh": None, "instance_cells": np.zeros((0, 3), np.float32)})
        return out
    mesh = int(tree.mesh_index[instance])
    mesh_tree = tree.meshes[mesh]
    drawn = geometry.FLAT_DRAWN[mesh_tree.structure]
    # The subtree under the cursor: the flat overlay's, with the cursor in
    # the instance's object space.
    start = geometry.subtree_root(mesh_tree, settings, object_point(tree, instance, cursor))
    if start is None:
        # instance_at found the point inside the mesh's box; a BVH's
        # node_at may still find no leaf box holding it.
        out = geometry.empty_geometry("3D cursor is in no leaf box of the instance's tree")
    else:
        out = drawn.make(InstanceView(tree, instance), settings, *start)
    out.update({"mesh": mesh, "instance_cells": out[drawn.cells_key]})
    return out
