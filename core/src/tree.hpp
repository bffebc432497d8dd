// The flat, compact tree: 8-byte nodes in depth-first order, one shared array
// of triangle references, and a plane array for general (non-axis) nodes.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "geometry.hpp"

namespace bsp {

// A node is 8 bytes. The low two bits of `bits` say the kind:
//   0, 1, 2  kd interior node: `split` is the plane position along that axis,
//            bits >> 2 the index of the child above the plane;
//   3        leaf or general node, told apart by bit 2:
//     leaf     (bit 2 clear): bits >> 3 is the reference count and `first`
//              the offset into the reference array - or, for a one-triangle
//              leaf, the triangle itself, which saves one indirection;
//     general  (bit 2 set): `first` indexes planes[] (n.x, n.y, n.z, d; the
//              plane n.x = d), bits >> 3 is the index of the child above.
// The child below (n.x < d) always follows its parent.
struct Node {
    union {
        float split;
        uint32_t first;
    };
    uint32_t bits;

    bool is_kd() const { return (bits & 3u) != 3u; }
    bool is_leaf() const { return (bits & 7u) == 3u; }
    bool is_general() const { return (bits & 7u) == 7u; }
    int axis() const { return int(bits & 3u); }
    uint32_t kd_above() const { return bits >> 2; }
    uint32_t count() const { return bits >> 3; }
    uint32_t general_above() const { return bits >> 3; }

    static Node kd(int axis, float split, uint32_t above) {
        Node n;
        n.split = split;
        n.bits = uint32_t(axis) | (above << 2);
        return n;
    }
    static Node general(uint32_t plane, uint32_t above) {
        Node n;
        n.first = plane;
        n.bits = 7u | (above << 3);
        return n;
    }
    static Node leaf(uint32_t first, uint32_t count) {
        Node n;
        n.first = first;
        n.bits = 3u | (count << 3);
        return n;
    }
};
static_assert(sizeof(Node) == 8, "nodes must stay 8 bytes");

struct Plane {
    float nx, ny, nz, d;
};

constexpr uint32_t kMaxNodes = (1u << 29) - 1;

enum class LeafBoxes : int {
    None = 0,      // no culling possible
    Triangle = 1,  // each triangle's own box: 24 bytes per triangle
    Clipped = 2,   // each reference's triangle clipped to its leaf cell: 24 bytes per reference
};

struct BuildOptions {
    float traversal_cost = 1.0f;   // K_d: one kd step (every step without ^Kd)
    float intersect_cost = 1.5f;   // K_i: one ray-triangle test
    float empty_bonus = 0.2f;
    int max_depth = 0;             // 0: 8 + 1.3 log2(N), as in pbrt
    int leaf_size = 1;             // nodes with this many triangles or fewer become leaves
    float max_duplication = 8.0f;  // references <= max_duplication * triangles
    double memory_limit_mb = 4096.0;
    int threads = 0;
    // The BSP family (ignored by the kd builder).
    // How the builder picks candidate directions at a node: a name in
    // strategy_names() (registry.hpp), each in its own strategies/*.cpp.
    std::string strategy = "axes";
    int k = 3;                     // directions per node, the axes included for "+" methods
    bool plus_axes = false;        // "+": the three axes are among the K
    bool kd_nodes = false;         // ^Kd: axis splits become cheap kd nodes
    int fixed_set = 0;             // RBSP: 0 golden spiral, 1 k-DOP, 2 axes + spiral
    uint64_t seed = 1;
    float alpha = 0.1f;            // ^Kd: K_d,BSP = alpha K_i (n - 1) + K_d
    float general_cost = 2.0f;     // ^Kd fallback: the constant K_d,BSP
    int cluster_iterations = 16;   // BSP_cn: k-means rounds at most
    int cluster_sample = 1024;     // BSP_cn: normals clustered per node at most
    int ize_candidates = 64;       // BSP_IZE: triangles whose planes are tried per node at most
    // Leaf culling with the ray segment's box (seed 002): which boxes to keep.
    LeafBoxes leaf_boxes = LeafBoxes::Triangle;
};

struct LevelStats {
    uint64_t planes = 0;      // interior nodes at this depth
    uint64_t directions = 0;  // distinct split directions among them
};

struct BuildStats {
    double build_seconds = 0;
    uint64_t triangles = 0, degenerate = 0;
    uint64_t nodes = 0, interior_nodes = 0, kd_nodes = 0, general_nodes = 0;
    uint64_t leaves = 0, empty_leaves = 0;
    uint64_t references = 0, max_leaf_size = 0;
    int max_depth = 0, depth_limit = 0;
    double mean_leaf_depth = 0, sah_cost = 0;
    uint64_t bytes = 0, box_bytes = 0;
    uint64_t peak_bytes = 0;  // the most the memory budget counted at once during the build
    std::vector<LevelStats> levels;
    // Signs of a degenerate tree (degeneracy_warnings() in build_tree.cpp), one sentence each.
    std::vector<std::string> warnings;
};

struct Tree {
    // Input numbering, degenerate ones included, multiplied by `scale`: a
    // power of two that brings the largest coordinate into [1, 2) (exact).
    // Rays are scaled the same way on the way in, distances on the way out.
    std::vector<Triangle> triangles;
    double scale = 1.0;
    std::vector<Node> nodes;
    std::vector<uint32_t> refs;
    std::vector<Plane> planes;
    // Culling boxes: per triangle (LeafBoxes::Triangle) or per reference slot
    // of refs[] (LeafBoxes::Clipped, where leaves never inline a triangle).
    std::vector<Box> boxes;
    float cull_pad = 0;  // padding of the segment box: beyond any float error of the traversal
    Box bounds;
    BuildOptions options;
    BuildStats stats;
};

}  // namespace bsp
