// A node of the BVH's 4-wide traversal layout (Tree::bvh_wide): the
// children of up to two levels of the binary tree (bvh_node.hpp) collapsed
// into one node (builders/bvh_collapse.hpp), 128 bytes, two cache lines.
//
// The children's boxes are stored axis by axis (lo[k][lane], hi[k][lane]):
// one aligned load per face gives that face of all four children, so one
// node costs six loads and one four-lane slab test (kernels/
// bvh_wide_single_ray.hpp) where the binary walk takes two pair tests and
// two nodes' worth of cache lines. Per lane:
//   interior  count = kInterior, child = the wide node's index;
//   leaf      count = its triangles, child = their offset in refs[];
//   unused    an inverted box (+inf, -inf) that no ray enters, count 0.
// A leaf's `child` also indexes Tree::bvh_leaf_tris, its triangles copied
// in leaf order with their indices (BvhLeafTriangle).
// Why 4 lanes and not Embree's 8: SSE is on every x86-64, so one node
// layout serves every instruction-set level (docs/performance.md, "The BVH").
#pragma once
#include <cassert>
#include <cstdint>
#include <limits>

#include "geometry.hpp"

namespace bsp {

struct alignas(64) BvhWideNode {
    static constexpr int kWidth = 4;
    static constexpr uint32_t kInterior = 0xFFFFFFFFu;

    float lo[3][kWidth];
    float hi[3][kWidth];
    uint32_t child[kWidth];
    uint32_t count[kWidth];

    constexpr bool is_leaf(int lane) const { return count[lane] != kInterior; }
    constexpr uint32_t node(int lane) const {
        assert(!is_leaf(lane));
        return child[lane];
    }
    constexpr uint32_t first(int lane) const {
        assert(is_leaf(lane));
        return child[lane];
    }
    constexpr uint32_t leaf_count(int lane) const {
        assert(is_leaf(lane));
        return count[lane];
    }
    Box box(int lane) const {
        return {Vec3(lo[0][lane], lo[1][lane], lo[2][lane]),
                Vec3(hi[0][lane], hi[1][lane], hi[2][lane])};
    }

    // Every lane unused: inverted boxes, leaves of nothing.
    static BvhWideNode empty() {
        BvhWideNode n{};
        constexpr float inf = std::numeric_limits<float>::infinity();
        for (int k = 0; k < 3; ++k)
            for (int l = 0; l < kWidth; ++l) {
                n.lo[k][l] = inf;
                n.hi[k][l] = -inf;
            }
        return n;
    }
    void set(int lane, const Box& b, uint32_t c, uint32_t n) {
        for (int k = 0; k < 3; ++k) {
            lo[k][lane] = b.lo[k];
            hi[k][lane] = b.hi[k];
        }
        child[lane] = c;
        count[lane] = n;
    }
};
static_assert(sizeof(BvhWideNode) == 128, "wide BVH nodes must stay 128 bytes");

// A triangle of a wide leaf, copied in leaf order with its index: a leaf's
// triangles side by side, and no read of refs[] to learn which they are
// (one cache miss less per leaf on incoherent rays).
struct BvhLeafTriangle {
    Triangle tri;
    uint32_t prim;
};
static_assert(sizeof(BvhLeafTriangle) == 40, "leaf triangles are nine floats and an index");

}  // namespace bsp
