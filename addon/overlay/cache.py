# SPDX-License-Identifier: GPL-3.0-or-later
"""The overlay's arrays of the kept tree, made through one table keyed on
`tree.structure` and kept until the tree, the settings or the cursor they
depend on change (no bpy: the tests without Blender use it)."""

import weakref
from typing import NamedTuple

from . import geometry, in_place


class Drawn(NamedTuple):
    """What the overlay draws of one kind of tree."""

    make: object  # (tree, settings, cursor) -> the arrays
    # Whether the arrays depend on the 3D cursor whatever the scope: a
    # two-level build draws the instance under it.
    follows_cursor: bool


# The overlay by the tree's kind (tree.structure).
DRAWN = {
    "bsp": Drawn(geometry.overlay_geometry, False),
    "bvh": Drawn(geometry.overlay_geometry, False),
    "two_level": Drawn(in_place.two_level_geometry, True),
}


class GeometryCache:
    """The last overlay geometry and what it was made from: the draw handler
    and the panel ask every redraw, the core walks only when the tree, the
    settings or (in the cursor scope) the cursor changed. Holds the tree
    weakly: a forgotten tree must be freed, not kept alive by the overlay."""

    def __init__(self):
        self.clear()

    def clear(self):
        self._tree = lambda: None
        self._key = None
        self._geometry = None
        self.builds = 0  # how many times the core was asked: for the tests

    def made_from(self, tree):
        """True when the kept geometry was made from `tree`."""
        return tree is not None and self._tree() is tree

    def get(self, tree, settings, cursor=None):
        if tree is None:
            self.clear()
            return None
        drawn = DRAWN[tree.structure]
        follows_cursor = settings.scope == "cursor" or drawn.follows_cursor
        key = (settings, tuple(cursor) if follows_cursor and cursor else None)
        if self._tree() is not tree or key != self._key:
            self._geometry = drawn.make(tree, settings, cursor)
            self._tree, self._key = weakref.ref(tree), key
            self.builds += 1
        return self._geometry
