// The tree as geometry, for drawing it: the split plane of every interior
// node clipped to its cell, the cells themselves, and the node whose cell
// holds a point. Cells come from the convex cell code (cell.hpp) in the
// tree's scaled space; every vertex handed out is in world units.
#pragma once
#include <cstddef>
#include <cstdint>
#include <vector>

#include "builders/cell.hpp"
#include "frame.hpp"
#include "tree.hpp"

namespace bsp {

// Convex polygons in one flat array: polygon i has the vertices
// [offsets[i], offsets[i + 1]) of `vertices` (x, y, z each, world units).
// The layout a GPU batch draws from directly.
struct PolygonSoup {
    std::vector<float> vertices;
    std::vector<uint32_t> offsets{0};
    size_t size() const { return offsets.size() - 1; }
    void add(const Vec3d* p, size_t n, const Tree& tree);  // in world units
};

// One polygon per interior node: its split plane inside its cell.
struct SplitPolygons {
    PolygonSoup polygons;
    std::vector<uint32_t> node;
    std::vector<int32_t> depth;  // below the walk's root, which has depth 0
    std::vector<uint8_t> kind;   // NodeKind
    std::vector<double> planes;  // n.x, n.y, n.z, d per polygon (world units)
    bool cut = false;            // max_polygons stopped the walk
};

// Cells as closed polyhedra: cell i has the faces [cell_offsets[i],
// cell_offsets[i + 1]) of `faces`.
struct NodeCells {
    PolygonSoup faces;
    std::vector<uint32_t> cell_offsets{0};
    std::vector<uint32_t> node;
    std::vector<int32_t> depth;
    std::vector<uint8_t> kind;  // Leaf, or the kind of an interior node cut off by max_depth
    bool cut = false;           // max_cells stopped the walk
};

// A node's split plane n.x = d in the world (kd: the axis; general: the
// stored plane, its offset unscaled); false for a leaf.
bool world_plane(const Tree& tree, uint32_t index, double plane[4]);

// The split planes of the interior nodes at most `max_depth` levels below
// `root`, level by level (so a cut keeps the shallow levels whole), at most
// `max_polygons` of them. A plane splitting a flat cell (a slab of zero
// thickness: a wall's own cell) meets it in a segment and yields no polygon. Throws std::invalid_argument for a negative
// depth or a root out of range.
SplitPolygons split_polygons(const Tree& tree, int max_depth, uint32_t root, size_t max_polygons);

// The cells of the leaves at most `max_depth` levels below `root`, and of
// the interior nodes at exactly that depth: together they tile root's cell.
// A negative max_depth means no limit.
NodeCells node_cells(const Tree& tree, int max_depth, uint32_t root, size_t max_cells);

// The node at most `max_depth` levels deep (negative: a leaf) whose cell
// holds the world point p, and its depth; {-1, -1} when p is outside the
// tree's box. A point on a plane belongs to the side above it, as in the
// builders (below is n.x < d).
struct NodeAt {
    int64_t node;
    int32_t depth;
};
NodeAt node_at(const Tree& tree, const double p[3], int max_depth);

}  // namespace bsp
