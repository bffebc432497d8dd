#include "trace_path.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "kernels/tree_view.hpp"
#include "triangle.hpp"

// The rules below are the single-ray kernel's counting path
// (kernels/single_ray.hpp, trace_one with CountEvery); the comments there say
// why each one is as it is. Any change there must be made here too:
// test_tree_geometry.py compares this walk with intersect() on every method.

namespace bsp {
namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

// The kernel's direct-mapped table of the last triangles tested.
class RecentTests {
public:
    RecentTests() { std::fill(slot_, slot_ + kSize, 0xFFFFFFFFu); }
    bool seen(uint32_t prim) {
        uint32_t& s = slot_[prim & (kSize - 1)];
        const bool was = s == prim;
        s = prim;
        return was;
    }

private:
    static constexpr uint32_t kSize = 16;
    uint32_t slot_[kSize];
};

// The ray's range [t0, t1] inside the box; false when it misses.
bool range_in_box(const Box& b, const Vec3& o, const Vec3& inv, const Vec3& d, float& t0,
                  float& t1) {
    for (int k = 0; k < 3; ++k) {
        if (d[k] == 0.0f) {
            if (o[k] < b.lo[k] || o[k] > b.hi[k]) return false;
            continue;
        }
        float near = (b.lo[k] - o[k]) * inv[k], far = (b.hi[k] - o[k]) * inv[k];
        if (near > far) std::swap(near, far);  // a swap, not min/max: the same answer for NaN
        far *= 1.0f + 4.0f * std::numeric_limits<float>::epsilon();
        t0 = std::max(t0, near);
        t1 = std::min(t1, far);
        if (t0 > t1) return false;
    }
    return true;
}

// The padded box of the segment o + [t0, t1] d that culling tests against.
Box segment_box(const Vec3& o, const Vec3& d, float t0, float t1, float pad) {
    const float tmag = std::max(std::fabs(t0), std::fabs(t1));
    Box box;
    for (int k = 0; k < 3; ++k) {
        const float a = o[k] + t0 * d[k], b = o[k] + t1 * d[k];
        const float p = pad + (std::fabs(o[k]) + tmag * std::fabs(d[k])) * (1.0f / (1 << 20));
        box.lo[k] = std::min(a, b) - p;
        box.hi[k] = std::max(a, b) + p;
    }
    return box;
}

bool boxes_miss(const Box& a, const Box& b) {
    return a.lo.x > b.hi.x || a.hi.x < b.lo.x || a.lo.y > b.hi.y || a.hi.y < b.lo.y ||
           a.lo.z > b.hi.z || a.hi.z < b.lo.z;
}

struct Pending {
    uint32_t node;
    int32_t depth;
    float t0, t1;
};

// Where the ray crosses an interior node's plane, widened by its error for
// general planes, and which child it enters first.
struct Crossing {
    float t_lo, t_hi;
    uint32_t entry, exit;
};

class PathRecorder {
public:
    PathRecorder(const Tree& tree, const Vec3& o, const Vec3& d, float tmin, float tmax, bool cull)
        : tree_(tree), view_(make_tree_view(tree)), o_(o), d_(d),
          inv_(1.0f / d.x, 1.0f / d.y, 1.0f / d.z), sray_(o, d), tmin_(tmin),
          boxes_(cull ? tree.options.leaf_boxes : LeafBoxes::None) {
        constexpr float kCrossUlps = 1.0f / (1 << 20);
        cross_a_ = kCrossUlps *
                   (view_.two_scene_scale + std::fabs(o.x) + std::fabs(o.y) + std::fabs(o.z));
        cross_b_ = kCrossUlps * (std::fabs(d.x) + std::fabs(d.y) + std::fabs(d.z));
        path_.t = tmax;
    }

    TracePath run(float tmax) {
        float t0 = tmin_, t1 = tmax;
        if (!range_in_box(view_.bounds, o_, inv_, d_, t0, t1)) return std::move(path_);
        Pending at{0, 0, t0, t1};
        for (;;) {
            const Node& node = tree_.nodes[at.node];
            const uint32_t step = uint32_t(path_.steps.size());
            path_.steps.push_back({at.node, at.depth, uint8_t(node.kind()), at.t0, at.t1});
            ++path_.n_steps;
            if (!node.is_leaf()) {
                descend(node, at);
                continue;
            }
            if (node.count() != 0) test_leaf(node, at, step);
            if (!pop(at)) break;
        }
        return std::move(path_);
    }

private:
    const Tree& tree_;
    TreeView view_;
    Vec3 o_, d_, inv_;
    ShearedRay sray_;
    float tmin_;
    LeafBoxes boxes_;
    float cross_a_ = 0, cross_b_ = 0;
    RecentTests recent_;
    std::vector<Pending> stack_;
    TracePath path_;

    Crossing cross(const Node& node, uint32_t index) {
        const float org[3] = {o_.x, o_.y, o_.z}, dir[3] = {d_.x, d_.y, d_.z};
        float tplane, err = 0.0f;
        bool down;
        uint32_t above;
        if (node.is_kd()) {
            const int axis = node.axis();
            tplane = (node.split - org[axis]) * inv_[axis];
            down = std::signbit(dir[axis]);
            above = node.kd_above();
        } else {
            ++path_.n_general_steps;
            const Plane& p = tree_.planes[node.first];
            const float no = p.nx * org[0] + p.ny * org[1] + p.nz * org[2];
            const float nd = p.nx * dir[0] + p.ny * dir[1] + p.nz * dir[2];
            const float inv_nd = 1.0f / nd;
            tplane = (p.d - no) * inv_nd;
            const bool axis_plane = (p.nx == 0.0f) + (p.ny == 0.0f) + (p.nz == 0.0f) == 2;
            if (axis_plane) err = 0.0f;
            else if (nd != 0.0f) err = (cross_a_ + std::fabs(tplane) * cross_b_) * std::fabs(inv_nd);
            else err = std::fabs(p.d - no) > cross_a_ ? 0.0f : kNaN;
            down = std::signbit(nd);
            above = node.general_above();
        }
        const uint32_t below = index + 1;
        return {tplane - err, tplane + err, down ? above : below, down ? below : above};
    }

    // Into the child (or children) the ray's range reaches; the far one of
    // two waits on the stack.
    void descend(const Node& node, Pending& at) {
        const Crossing c = cross(node, at.node);
        const int32_t depth = at.depth + 1;
        if (c.t_hi < at.t0) {
            at = {c.exit, depth, at.t0, at.t1};
        } else if (c.t_lo > at.t1) {
            at = {c.entry, depth, at.t0, at.t1};
        } else {
            stack_.push_back({c.exit, depth, std::max(at.t0, c.t_lo), at.t1});
            at = {c.entry, depth, at.t0, std::min(at.t1, c.t_hi)};
        }
    }

    Box segment(const Pending& at) const {
        return segment_box(o_, d_, at.t0, std::min(at.t1, path_.t), tree_.cull_pad);
    }

    void test_leaf(const Node& node, const Pending& at, uint32_t step) {
        const uint32_t n_refs = node.count();
        const uint32_t* list = n_refs == 1 && view_.inline_single ? &tree_.nodes[at.node].first
                                                                  : tree_.refs.data() + node.first;
        Box seg;
        if (boxes_ != LeafBoxes::None) seg = segment(at);
        for (uint32_t i = 0; i < n_refs; ++i) {
            const uint32_t p = list[i];
            if (boxes_ != LeafBoxes::None) {
                const Box& b = tree_.boxes[boxes_ == LeafBoxes::Triangle ? p : node.first + i];
                if (boxes_miss(b, seg)) {
                    ++path_.n_culled;
                    path_.tests.push_back({step, p, TestResult::Culled, kNaN});
                    continue;
                }
            }
            if (recent_.seen(p)) {
                path_.tests.push_back({step, p, TestResult::Seen, kNaN});
                continue;
            }
            ++path_.n_tests;
            TriangleHit th;
            if (!intersect_triangle(sray_, tree_.triangles[p], tmin_, path_.t, th)) {
                path_.tests.push_back({step, p, TestResult::Miss, kNaN});
                continue;
            }
            path_.t = th.t;
            path_.prim = int32_t(p);
            path_.u = th.u;
            path_.v = th.v;
            path_.tests.push_back({step, p, TestResult::Hit, th.t});
            if (boxes_ != LeafBoxes::None) seg = segment(at);
        }
    }

    // The next waiting cell that may still hold a closer hit.
    bool pop(Pending& at) {
        while (!stack_.empty()) {
            const Pending e = stack_.back();
            stack_.pop_back();
            if (!(path_.t < e.t0)) {
                at = e;
                return true;
            }
        }
        return false;
    }
};

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
    const Vec3 org = s == 1.0 ? Vec3(o[0], o[1], o[2])
                              : Vec3(float(o[0] * s), float(o[1] * s), float(o[2] * s));
    const float lo = s == 1.0 ? tmin : float(tmin * s), hi = s == 1.0 ? tmax : float(tmax * s);
    TracePath path = PathRecorder(tree, org, dir, lo, hi, cull).run(hi);
    unscale(path, s, tmax);
    const bool hit = path.prim >= 0;
    if (!hit) {
        path.t = std::numeric_limits<float>::infinity();
        path.u = path.v = 0.0f;
    }
    return path;
}

}  // namespace bsp
