// A node of the BVH's 8-wide traversal layout (Tree::bvh_wide): up to
// eight nodes of the binary tree (bvh_node.hpp) below one binary node,
// collapsed into one node (builders/bvh_collapse.hpp), 256 bytes, four
// cache lines.
//
// The children's boxes are stored axis by axis (lo[k][lane], hi[k][lane]):
// one aligned load per face gives that face of all eight children, so one
// node costs six loads and one eight-lane slab test (kernels/
// bvh_wide_single_ray.hpp) where the binary walk takes up to seven pair
// tests and as many nodes' cache lines. Per lane:
//   interior  count = kInterior, child = the wide node's index;
//   leaf      count = its triangles, child = their offset in refs[];
//   unused    an inverted box (+inf, -inf) that no ray enters, count 0.
// A leaf's `child` also indexes Tree::bvh_leaf_tris, its triangles copied
// in leaf order with their indices (BvhLeafTriangle).
// Why 8 lanes, as Embree's: an AVX register holds a face of all eight
// children, so the AVX2 and AVX-512 levels test a node in one instruction
// per step of the slab test, and the SSE level in two; and a ray visits
// about two thirds of the 4-wide layout's nodes (docs/performance.md, "The
// BVH", has both layouts' figures).
#pragma once
#include <cassert>
#include <cstdint>
#include <limits>

#include "geometry.hpp"

namespace bsp {

struct alignas(64) BvhWideNode {
    static constexpr int kWidth = 8;
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
static_assert(sizeof(BvhWideNode) == 256, "wide BVH nodes must stay 256 bytes");

// A triangle of a wide leaf, copied in leaf order with its index: a leaf's
// triangles side by side, and no read of refs[] to learn which they are
// (one cache miss less per leaf on incoherent rays).
struct BvhLeafTriangle {
    Triangle tri;
    uint32_t prim;
};
static_assert(sizeof(BvhLeafTriangle) == 40, "leaf triangles are nine floats and an index");

}  // namespace bsp
