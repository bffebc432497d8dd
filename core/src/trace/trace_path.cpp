#include "trace/trace_path.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <unordered_map>

#include "trace/kernels/tree_view.hpp"
#include "trace/triangle.hpp"

// The single-ray kernel itself, instantiated here at the baseline
// instruction set with a policy that records its walk instead of counting
// it: the path is intersect()'s by construction, not by a copy of its rules.
// Like every instantiation of the kernel headers, it lives in a namespace of
// its own with internal linkage (see kernels/trace_kernels.cpp).
#define BSPLAB_ISA_NS path_walk
#include "trace/kernels/bvh_single_ray.hpp"
#include "trace/kernels/bvh_wide_single_ray.hpp"
#include "trace/kernels/single_ray.hpp"

namespace bsp {
namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

// What both recorders share: the path so far, the depths of the nodes still
// to visit (a node's depth is its parent's plus one: the parent was visited
// before it, and the record keeps the depths of the children of every
// interior node it visits), and the triangle tests of the visited leaves.
class PathRecorder {
public:
    void test(uint32_t prim) {
        ++path_.n_tests;
        tested_ = prim;
    }
    void hit(float t) { record(tested_, TestResult::Hit, t); }
    void miss() { record(tested_, TestResult::Miss, kNaN); }

    TracePath take(const path_walk::Closest& closest) {
        path_.t = closest.t;
        path_.prim = closest.prim;
        path_.u = closest.u;
        path_.v = closest.v;
        return std::move(path_);
    }

protected:
    explicit PathRecorder(const Tree& tree) : tree_(tree) { depth_of_[0] = 0; }

    // Records node `index` of `kind` over the walk's range [s0, s1] from
    // t_e, back in the ray's t; returns its depth.
    int32_t record_step(uint32_t index, NodeKind kind, float s0, float s1, double t_e) {
        const int32_t depth = depth_of_.at(index);
        path_.steps.push_back({index, depth, uint8_t(kind), float(t_e + s0), float(t_e + s1)});
        ++path_.n_steps;
        return depth;
    }
    // A triangle belongs to the leaf visited last.
    void record(uint32_t prim, TestResult result, float t) {
        path_.tests.push_back({uint32_t(path_.steps.size() - 1), prim, result, t});
    }

    const Tree& tree_;
    std::unordered_map<uint32_t, int32_t> depth_of_;
    uint32_t tested_ = 0;
    TracePath path_;
};

// The kernel's counter hooks (CountEvery in single_ray.hpp), recording each
// visited node and each triangle reference of the visited leaves.
class PathRecord : public PathRecorder {
public:
    explicit PathRecord(const Tree& tree) : PathRecorder(tree) {}

    // The walk starts again as the in-plane walk (single_ray.hpp, trace_ray):
    // the path is that walk's.
    void restart() {
        path_ = TracePath();
        depth_of_.clear();
        depth_of_[0] = 0;
    }

    void step(uint32_t index, float s0, float s1, double t_e) {
        const Node& node = tree_.nodes[index];
        const int32_t depth = record_step(index, node.kind(), s0, s1, t_e);
        if (node.is_leaf()) return;
        depth_of_[index + 1] = depth + 1;
        depth_of_[node.is_kd() ? node.kd_above() : node.general_above()] = depth + 1;
    }
    void general_step() { ++path_.n_general_steps; }
    void cull(uint32_t prim) {
        ++path_.n_culled;
        record(prim, TestResult::Culled, kNaN);
    }
    void seen(uint32_t prim) { record(prim, TestResult::Seen, kNaN); }
};

// The BVH kernel's hooks (BvhCountEvery), recording as PathRecord does, in
// the binary tree's numbering. The wide walk enters a wide node's lanes,
// binary nodes up to kLaneLevels below the node it visited last on that
// branch: a visited interior node sets the depths of its descendants that
// deep.
class BvhPathRecord : public PathRecorder {
public:
    explicit BvhPathRecord(const Tree& tree) : PathRecorder(tree) {}

    void step(uint32_t index, float s0, float s1, double t_e) {
        const BvhNode& node = tree_.bvh_nodes[index];
        const int32_t depth =
            record_step(index, node.is_leaf() ? NodeKind::Leaf : NodeKind::Box, s0, s1, t_e);
        set_depths(index, depth, kLaneLevels);
    }
    void box_test(uint32_t n) { path_.n_box_tests += n; }

private:
    // A wide node of W lanes opens at most W - 2 of its binary nodes'
    // children: its lanes lie at most W - 1 levels below the binary node it
    // stands for.
    static constexpr int kLaneLevels = BvhWideNode::kWidth - 1;

    void set_depths(uint32_t index, int32_t depth, int levels) {
        const BvhNode& node = tree_.bvh_nodes[index];
        if (node.is_leaf() || levels == 0) return;
        for (const uint32_t c : {node.left(), node.right()}) {
            depth_of_[c] = depth + 1;
            set_depths(c, depth + 1, levels - 1);
        }
    }
};

// The kernel's loop for this tree and culling mode, as trace_single_rays
// picks it on the counting path.
template <LeafBoxes kBoxes>
void walk(const TreeView& view, const Vec3& o, const Vec3& d, float tmin, float tmax,
          path_walk::Closest& closest, PathRecord& record) {
    if (view.has_general)
        path_walk::trace_ray<kBoxes, true, false, false>(view, o, d, tmin, tmax, closest, record);
    else
        path_walk::trace_ray<kBoxes, false, false, false>(view, o, d, tmin, tmax, closest, record);
}

TracePath record_path(const Tree& tree, const Vec3& o, const Vec3& d, float tmin, float tmax,
                      bool cull) {
    const TreeView view = make_tree_view(tree);
    if (tree.structure == Structure::Bvh) {
        BvhPathRecord record(tree);
        path_walk::Closest closest;
        path_walk::bvh_wide_trace_one(view, o, d, tmin, tmax, closest, record);
        return record.take(closest);
    }
    PathRecord record(tree);
    path_walk::Closest closest;
    switch (cull ? tree.options.leaf_boxes : LeafBoxes::None) {
        case LeafBoxes::None: walk<LeafBoxes::None>(view, o, d, tmin, tmax, closest, record); break;
        case LeafBoxes::Triangle:
            walk<LeafBoxes::Triangle>(view, o, d, tmin, tmax, closest, record);
            break;
        case LeafBoxes::Clipped:
            walk<LeafBoxes::Clipped>(view, o, d, tmin, tmax, closest, record);
            break;
    }
    return record.take(closest);
}

// Distances of the scaled space back in world units, as the kernel's ray
// loop does; a hit beyond tmax after unscaling is no hit.
void unscale(TracePath& path, double scale, float tmax) {
    const double inv = 1.0 / scale;
    for (PathStep& s : path.steps) {
        s.t0 *= inv;
        s.t1 *= inv;
    }
    for (PathTest& t : path.tests)
        if (t.result == TestResult::Hit) t.t = float(t.t * inv);
    if (scale != 1.0) {
        path.t = float(path.t * inv);
        if (!(path.t < tmax)) path.prim = -1;
    }
}

}  // namespace

TracePath trace_path(const Tree& tree, const float o[3], const float d[3], float tmin, float tmax,
                     bool cull) {
    const double s = tree.scale;
    const Vec3 dir(d[0], d[1], d[2]);
    // Into the tree's frame and scaled space, as the kernels' ray loops.
    const Vec3 org = to_frame(tree.offset, s, o);
    const float lo = s == 1.0 ? tmin : float(tmin * s), hi = s == 1.0 ? tmax : float(tmax * s);
    TracePath path = record_path(tree, org, dir, lo, hi, cull);
    unscale(path, s, tmax);
    const bool hit = path.prim >= 0;
    if (!hit) {
        path.t = std::numeric_limits<float>::infinity();
        path.u = path.v = 0.0f;
    }
    return path;
}

}  // namespace bsp
