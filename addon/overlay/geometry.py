# SPDX-License-Identifier: GPL-3.0-or-later
"""What the viewport overlay draws, as plain numpy arrays (no bpy, no gpu).

`overlay_geometry(tree, settings, cursor)` turns the core's split polygons
and cells into the three batches the draw handler makes once per change:
translucent faces of the split planes, their outlines, and (on request) the
wireframes of the cells. Keeping this free of Blender lets the tests without
Blender and those in Blender check exactly what is handed to `batch_for_shader`,
while the GPU drawing itself is only seen in the GUI check under Xvfb.
"""

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from .. import backend
from ..drawing import boxes

# Planes' colours by kind (RGB), the panel's defaults: the axis colours of
# Blender's own gizmos for kd planes, yellow for general planes.
DEFAULT_KIND_COLOURS = (
    (0.90, 0.20, 0.20),  # x
    (0.30, 0.80, 0.20),  # y
    (0.20, 0.40, 1.00),  # z
    (1.00, 0.85, 0.10),  # general
)
# The depth ramp's ends (depth 0 and the slider's depth): warm at the root,
# cool at the leaves, distinct from the kind colours' pure axes.
DEPTH_RAMP = ((1.00, 0.55, 0.05), (0.10, 0.70, 1.00))
# The outlines are drawn opaque over the translucent faces so the plane's
# edges stay visible when the faces are faint.
OUTLINE_ALPHA = 0.9
CELL_COLOUR = (0.92, 0.92, 0.92, 0.55)
# When the cap cuts the walk, the total is counted by a second walk allowed
# this many times the cap; past that the note says "more than".
COUNT_FACTOR = 10

COLOUR_MODES = ("kind", "depth")
SCOPES = ("whole", "cursor")


@dataclass(frozen=True)
class OverlaySettings:
    """Everything the overlay's geometry depends on besides the tree (and
    the 3D cursor in the "cursor" scope). Frozen: it is the cache key."""

    max_depth: int = 8
    colour_by: str = "kind"  # COLOUR_MODES
    cells: bool = False  # leaf cells as wireframes
    scope: str = "whole"  # SCOPES: the whole tree or the subtree under the cursor
    subtree_depth: int = 0  # depth of the subtree's root on the cursor's path
    alpha: float = 0.25  # of the filled planes
    cap: int = 20_000  # most polygons (and most cells) drawn
    kind_colours: tuple = DEFAULT_KIND_COLOURS  # x, y, z, general

    def __post_init__(self):
        if self.colour_by not in COLOUR_MODES:
            raise ValueError(f"colour_by must be one of {COLOUR_MODES}, got {self.colour_by!r}")
        if self.scope not in SCOPES:
            raise ValueError(f"scope must be one of {SCOPES}, got {self.scope!r}")
        for name in ("max_depth", "subtree_depth"):
            if getattr(self, name) < 0:
                raise ValueError(f"{name} must be >= 0, got {getattr(self, name)}")
        if self.cap < 1:
            raise ValueError(f"cap must be >= 1, got {self.cap}")
        if not 0.0 <= self.alpha <= 1.0:
            raise ValueError(f"alpha must be in [0, 1], got {self.alpha}")
        if len(self.kind_colours) != 4:
            raise ValueError("kind_colours needs four RGB colours: x, y, z, general")


def settings_of(props):
    """The panel's properties (`Scene.bsplab_overlay`, read attribute by
    attribute) as an OverlaySettings (the cache key)."""
    return OverlaySettings(
        max_depth=props.max_depth, colour_by=props.colour_by, cells=props.cells,
        scope=props.scope, subtree_depth=props.subtree_depth, alpha=round(props.alpha, 4),
        cap=props.cap,
        kind_colours=tuple(tuple(round(c, 4) for c in colour) for colour in (
            props.colour_x, props.colour_y, props.colour_z, props.colour_general)))


def kind_colour_table(settings):
    """(5, 3) RGB per core kind code (KINDS: x, y, z, leaf, general); a
    leaf never has a plane, its row is unused."""
    x, y, z, general = settings.kind_colours
    return np.array([x, y, z, (0.0, 0.0, 0.0), general], np.float32)


def depth_colours(depth, max_depth):
    """(P, 3) RGB on the depth ramp: depth 0 at one end, max_depth at the other."""
    t = (np.asarray(depth, np.float32) / max(max_depth, 1)).clip(0.0, 1.0)[:, None]
    low, high = (np.array(c, np.float32) for c in DEPTH_RAMP)
    return low + t * (high - low)


def polygon_colours(polygons, settings):
    """(P, 3) RGB, one per split polygon."""
    if settings.colour_by == "depth":
        return depth_colours(polygons["depth"], settings.max_depth)
    return kind_colour_table(settings)[polygons["kind"]]


def per_vertex(colours, offsets, alpha):
    """Each polygon's RGB repeated over its vertices, with `alpha`: (V, 4)."""
    counts = np.diff(np.asarray(offsets, np.int64))
    rgb = np.repeat(np.asarray(colours, np.float32).reshape(-1, 3), counts, axis=0)
    return np.hstack([rgb, np.full((len(rgb), 1), alpha, np.float32)])


def subtree_root(tree, settings, cursor):
    """(node, depth) the overlay starts from: the root for the whole tree,
    else the node `subtree_depth` levels deep on the 3D cursor's path (a
    shallower leaf if the path ends first); None when the cursor is outside
    the tree's box."""
    if settings.scope == "whole":
        return (0, 0)
    if cursor is None:
        raise ValueError('the "cursor" scope needs the 3D cursor location')
    return tree.node_at(cursor, max_depth=settings.subtree_depth)


def count_note(shown, cut, total, total_cut, cap, noun):
    """The panel's line about how much is drawn."""
    if not cut:
        return f"{shown:,} {noun}"
    of = f"more than {total:,}" if total_cut else f"{total:,}"
    return f"showing {shown:,} of {of} {noun} (cut at {cap:,})"


def _capped_walk(query, settings, root):
    """`query(max_depth, root, cap)` (a view's split_polygons or
    node_boxes) at the settings' cap, how many there are in all and whether
    that count was cut too."""
    found = query(settings.max_depth, root, settings.cap)
    total, total_cut = len(found["node"]), found["cut"]
    if found["cut"]:
        # How many there would be: a second walk, bounded, only when cut.
        counted = query(settings.max_depth, root, COUNT_FACTOR * settings.cap)
        total, total_cut = len(counted["node"]), counted["cut"]
    return found, total, total_cut


class TreeView:
    """A flat tree as the overlay walks it: its own queries (split_polygons,
    node_boxes, leaf_cells) and its boxes' wireframe. in_place.InstanceView
    answers the same for an instance of a two-level build, in the world."""

    # How the notes name what is drawn, and the node the cursor scope starts at.
    of = ""
    subtree = "node"

    def __init__(self, tree):
        self.tree = tree

    def split_polygons(self, depth, root, cap):
        return self.tree.split_polygons(depth, root=root, max_polygons=cap)

    def node_boxes(self, depth, root, cap):
        return self.tree.node_boxes(depth, root=root, max_boxes=cap)

    def leaf_cells(self, depth, root, cap):
        return self.tree.leaf_cells(max_depth=depth, root=root, max_cells=cap)

    @staticmethod
    def wireframe(found):
        return boxes.wireframe(found["lo"], found["hi"])


def empty_geometry(note):
    """Nothing to draw, and why."""
    vec3 = np.zeros((0, 3), np.float32)
    rgba = np.zeros((0, 4), np.float32)
    return {
        "face_positions": vec3, "face_colours": rgba, "face_indices": np.zeros((0, 3), np.uint32),
        "line_colours": rgba, "line_indices": np.zeros((0, 2), np.uint32),
        "cell_positions": vec3, "cell_colours": rgba, "cell_indices": np.zeros((0, 2), np.uint32),
        "polygons": 0, "polygon_total": 0, "cut": False, "cells": 0, "cells_cut": False,
        "root": None, "root_depth": None, "notes": [note],
    }


# Said on the panel for a BVH in place of the options it ignores.
BVH_NOTE = "a BVH: its node boxes, coloured by depth (no planes, no cells)"


def _subtree_note(view, settings, root, root_depth, out):
    if settings.scope == "cursor":
        out["notes"].insert(0, f"subtree of {view.subtree} {root:,} (depth {root_depth})")


def box_geometry(view, settings, root, root_depth):
    """A BVH's overlay: the wireframes of its node boxes down to
    `settings.max_depth` below `root`, coloured by depth whatever
    `colour_by` says (a box has no kind), in the arrays of
    overlay_geometry() (the edges are its "line_indices" over
    "face_positions"; there are no faces and no cells). `view`: a
    TreeView, or an in_place.InstanceView."""
    found, total, total_cut = _capped_walk(view.node_boxes, settings, root)
    shown = len(found["node"])
    positions, edges = view.wireframe(found)
    rgb = np.repeat(depth_colours(found["depth"], settings.max_depth), 8, axis=0)
    out = empty_geometry(count_note(shown, found["cut"], total, total_cut, settings.cap,
                                    "node boxes" + view.of))
    out.update({
        "face_positions": positions,
        "face_colours": np.hstack([rgb, np.full((len(rgb), 1), settings.alpha, np.float32)]),
        "line_colours": np.hstack([rgb, np.full((len(rgb), 1), OUTLINE_ALPHA, np.float32)]),
        "line_indices": edges,
        "polygons": shown, "polygon_total": total, "cut": bool(found["cut"]),
        "root": int(root), "root_depth": int(root_depth),
        "depth": found["depth"], "node": found["node"], "boxes": shown,
    })
    out["notes"].append(BVH_NOTE)
    _subtree_note(view, settings, root, root_depth, out)
    return out


def overlay_geometry(tree, settings, cursor=None):
    """The overlay's batches' arrays for `tree` (a bsplab.Tree):

    "face_positions" (V, 3) float32 and "face_colours" (V, 4) with
    "face_indices" (T, 3) uint32 (a "TRIS" batch: the split planes, clipped
    to their cells, translucent), "line_colours" (V, 4) and "line_indices"
    (E, 2) (a "LINES" batch over the same positions: their outlines),
    "cell_positions"/"cell_colours"/"cell_indices" (the cells' wireframe,
    empty unless settings.cells); the counts "polygons", "polygon_total",
    "cut", "cells", "cells_cut"; "root"/"root_depth" (the node drawn from)
    and "notes" (lines for the panel). `cursor` is the 3D cursor's world
    location, needed in the "cursor" scope. A BVH's are its node boxes
    (box_geometry): the same keys, "polygons" counting boxes.
    """
    drawn = FLAT_DRAWN[tree.structure]
    start = subtree_root(tree, settings, cursor)
    if start is None:
        return empty_geometry(drawn.outside_note)
    return drawn.make(TreeView(tree), settings, *start)


def plane_geometry(view, settings, root, root_depth):
    """A kd or BSP tree's overlay (overlay_geometry()): its split planes
    below `root`, and the cells the drawn planes cut root's cell into when
    asked (the leaves down to one level below the slider's depth, and the
    nodes at that level in place of their deeper subtrees, so the cells
    tile root's cell). `view`: a TreeView, or an in_place.InstanceView."""
    bsplab = backend.import_bsplab()
    polygons, total, total_cut = _capped_walk(view.split_polygons, settings, root)
    colours = polygon_colours(polygons, settings)
    shown = len(polygons["node"])
    out = empty_geometry(count_note(shown, polygons["cut"], total, total_cut, settings.cap,
                                    "split polygons" + view.of))
    out.update({
        "face_positions": np.ascontiguousarray(polygons["vertices"], np.float32),
        "face_colours": per_vertex(colours, polygons["offsets"], settings.alpha),
        "face_indices": np.ascontiguousarray(polygons["triangles"], np.uint32),
        "line_colours": per_vertex(colours, polygons["offsets"], OUTLINE_ALPHA),
        "line_indices": bsplab.polygons.edge_pairs(polygons["offsets"]),
        "polygons": shown, "polygon_total": total, "cut": bool(polygons["cut"]),
        "root": int(root), "root_depth": int(root_depth),
        "kind": polygons["kind"], "depth": polygons["depth"], "node": polygons["node"],
    })
    _subtree_note(view, settings, root, root_depth, out)
    if settings.cells:
        cells = view.leaf_cells(settings.max_depth + 1, root, settings.cap)
        vertices = np.ascontiguousarray(cells["vertices"], np.float32)
        out.update({
            "cell_positions": vertices,
            "cell_colours": np.tile(np.array(CELL_COLOUR, np.float32), (len(vertices), 1)),
            "cell_indices": np.ascontiguousarray(cells["edges"], np.uint32),
            "cells": len(cells["node"]), "cells_cut": bool(cells["cut"]),
        })
        cell_note = f"{len(cells['node']):,} cells{view.of}"
        out["notes"].append(cell_note + (f" (cut at {settings.cap:,})" if cells["cut"] else ""))
    return out


class FlatDrawn(NamedTuple):
    """What the overlay draws of one kind of flat tree."""

    make: object  # (view, settings, root, root_depth) -> the arrays
    outside_note: str  # said when the 3D cursor is in no node of the tree
    # The arrays' key of the wireframe of its cells: a BVH's node boxes are
    # what stands for cells.
    cells_key: str


# The flat overlay by the tree's structure (a two-level build's mesh trees too).
FLAT_DRAWN = {
    "bsp": FlatDrawn(plane_geometry, "3D cursor is outside the tree's box", "cell_positions"),
    "bvh": FlatDrawn(box_geometry, "3D cursor is in no leaf's box", "face_positions"),
}
