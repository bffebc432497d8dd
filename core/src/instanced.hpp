// An instanced scene in two levels: a tree per unique mesh, built in the
// mesh's object space by any method of the registry and shared by all its
// instances, and a top level - a BVH over the instances' world boxes
// (builders/bvh_build.hpp's build_bvh, the same binned SAH as a mesh's BVH).
//
// An instance is a mesh index and an affine 3 x 4 matrix, world from object
// (rotation, non-uniform scale, mirroring and shear allowed; a singular one
// is refused). A ray is carried into object space by the inverse, computed
// in double and rounded once to float, without renormalising the direction:
// a point o + t d in the world is o' + t d' in the object, so a bottom
// tree's t is the world's t and the closest hit over instances is the
// smallest t. The only difference from tracing the flattened scene is that
// rounding (docs/instances.md, and the oracle's rule for it).
#pragma once
#include <cassert>
#include <cstdint>
#include <string>
#include <vector>

#include "bvh_node.hpp"
#include "geometry.hpp"
#include "progress.hpp"
#include "trace/traverse.hpp"
#include "tree.hpp"

namespace bsp {

// What the trace reads of an instance: 104 bytes. The inverse stays in
// double: a small mesh far from the origin has a translation that nearly
// cancels the rotated ray origin, which a float matrix would round by a good
// part of the mesh (the world matrix itself stays with the caller).
struct Instance {
    double object_from_world[12];  // row-major 3 x 4: x_object = A x_world + b
    uint32_t mesh = 0;
};

struct InstancedStats {
    uint64_t meshes = 0, instances = 0;
    uint64_t top_nodes = 0, top_leaves = 0, top_bytes = 0;
    int top_depth = 0;
    double top_sah_cost = 0, top_build_seconds = 0;
    uint64_t instanced_triangles = 0;  // what the flattened scene would hold
};

// The top level's binary BVH (build_bvh's nodes, bvh_node.hpp) in the layout
// its walk reads: each pair of siblings in one 64-byte line - their boxes
// axis by axis, lanes (A.lo, B.lo, A.hi, B.hi), and their links (BvhNode's
// first and bits). So a step loads one line: the walk learns a child's
// link with its box, and its next load is that child's own pair, where
// BvhNode's layout took two dependent loads a step (the node, then its
// children) and a 4 x 4 transpose with a per-axis lane swap; the near and
// far faces come with two 8-byte loads per axis at offsets chosen once per
// ray by the direction's signs. The same 32 bytes a node as BvhNode; the
// root's box and link apart.
struct TopLevel {
    struct Link {
        uint32_t first = 0, bits = 0;  // as BvhNode: a leaf's top_order slot and count, or
                                       // kInteriorTag and the left child
        constexpr bool is_leaf() const { return bits != BvhNode::kInteriorTag; }
        constexpr uint32_t left() const {
            assert(!is_leaf());
            return first;
        }
        constexpr uint32_t count() const {
            assert(is_leaf());
            return bits;
        }
    };
    struct alignas(64) Pair {
        float axis[3][4];  // per axis: (A.lo, B.lo, A.hi, B.hi); A = node 2p + 1, B = 2p + 2
        Link link[2];      // A's, B's
    };
    Box root;
    Link root_link;
    std::vector<Pair> pairs;  // per pair of siblings (nodes 2p + 1 and 2p + 2)
    size_t nodes = 0;         // 0: no top level (no instance has a triangle)

    // From build_bvh's nodes (root first, each node's children a pair at
    // 2p + 1, 2p + 2); and the binary nodes back, for drawing and for
    // the recorded walk (trace/instanced_trace_path.hpp).
    static TopLevel from_nodes(const std::vector<BvhNode>& nodes);
    BvhNode node(size_t i) const;
    static const Pair& pair_of(const Pair* pairs, uint32_t left) { return pairs[(left - 1) >> 1]; }
    size_t size() const { return nodes; }
    bool empty() const { return nodes == 0; }
    size_t bytes() const { return sizeof(Box) + sizeof(Link) + pairs.size() * sizeof(Pair); }
};
static_assert(sizeof(TopLevel::Pair) == 64, "a top-level pair is one cache line");

struct InstancedScene {
    std::vector<const Tree*> meshes;  // not owned: the caller keeps the trees alive
    std::vector<Instance> instances;
    // The top level: a binary BVH (TopLevel), leaves indexing top_order,
    // which holds instance indices. Empty when no instance has a triangle.
    TopLevel top;
    std::vector<uint32_t> top_order;
    // The first index of instance i's triangles in the flattened scene
    // (instances in order, each mesh's triangles in input order): the tie
    // rule between instances (the smallest flattened index of equal t wins,
    // as within a tree the smallest triangle index).
    std::vector<uint64_t> flat_offset;
    InstancedStats stats;
};

// The top level's options: its BVH's bins and costs (instance boxes are
// few; a bottom trace costs many box steps, hence the default intersect
// cost). The defaults are named here once; the registry's "top" options
// (top_bins, top_traversal_cost, top_intersect_cost) take them as theirs,
// with their limits, and top_settings_for() (registry.hpp) fills these
// fields from option values by name, as a build's BuildOptions are filled.
constexpr int kTopBins = 16;
constexpr float kTopTraversalCost = 1.0f;
constexpr float kTopIntersectCost = 4.0f;

struct TopLevelSettings {
    int bins = kTopBins;
    float traversal_cost = kTopTraversalCost;
    float intersect_cost = kTopIntersectCost;
    int threads = 0;  // the registry's common "threads" (0: all cores)
};

// The matrices' own check, before any tree is built (build_instanced makes
// it again): throws std::invalid_argument naming the first instance whose
// matrix is non-finite or singular (instances x 12 numbers, row-major).
void check_instance_matrices(const std::vector<double>& matrices);

// Throws std::invalid_argument naming the instance for a mesh index out of
// range, a non-finite or singular matrix.
InstancedScene build_instanced(std::vector<const Tree*> meshes,
                               const std::vector<uint32_t>& mesh_index,
                               const std::vector<double>& matrices,  // instances x 12
                               const TopLevelSettings& settings, Progress* progress);

// The per-ray results of an instanced trace beyond the HitBatch's: the
// instance hit (-1 on a miss), and - for the counting path - the top level's
// node visits and the instances entered (the HitBatch's counters then hold
// the bottom trees' steps, tests and box tests, summed over the instances).
struct InstanceHits {
    int32_t* instance = nullptr;
    uint32_t* top_steps = nullptr;
    uint32_t* instance_visits = nullptr;
};

// Whether intersect_instanced()'s hits-only path traces this batch in
// spatial order (ray_order.hpp) on `threads` threads (0: all): never when
// every mesh tree is a BVH.
bool orders_batch(const InstancedScene& scene, const RayBatch& rays, RayOrder order, int threads);

// Closest hits: hits.prim is the triangle's index in its mesh.
// Without counter arrays an incoherent batch is traced in spatial order
// (`order`, as intersect()'s in traverse.hpp): the same hits.
void intersect_instanced(const InstancedScene& scene, const RayBatch& rays, HitBatch& hits,
                         InstanceHits& extra, int threads, Progress* progress = nullptr,
                         RayOrder order = RayOrder::Auto);

// The same hits, hits only (no counter arrays): groups of consecutive rays
// walk the top level together and go through each mesh tree's packet kernel
// together (a BVH mesh tree's: its single rays). Bit for bit but where a
// mesh tree's answer depends on the segment's end (below).
void intersect_instanced_packets(const InstancedScene& scene, const RayBatch& rays,
                                 HitBatch& hits, InstanceHits& extra, int threads,
                                 Progress* progress = nullptr);

}  // namespace bsp
