// A node of a bounding-volume hierarchy (Tree::bvh_nodes, Structure::Bvh):
// 32 bytes, binary, the layout of tinybvh's BVHNode - the box's low corner
// and `first`, the box's high corner and `bits`:
//   interior  bits = kInteriorTag: its children are nodes first and
//             first + 1 (always a pair, side by side, so that the traversal
//             reads both boxes from one or two cache lines);
//   leaf      bits = the triangle count, `first` the offset of its
//             triangles in refs[] (a leaf of 0 triangles is the empty tree's
//             root).
// Its own box is stored in the node (not in its parent): a node is then
// self-describing for drawing and for the ray inspector, and the traversal
// tests the two children's boxes at the parent, which costs the same reads.
#pragma once
#include <cassert>
#include <cstdint>

#include "geometry.hpp"

namespace bsp {

struct alignas(32) BvhNode {
    Vec3 lo;
    uint32_t first;
    Vec3 hi;
    uint32_t bits;

    static constexpr uint32_t kInteriorTag = 0xFFFFFFFFu;
    static constexpr uint32_t kMaxCount = kInteriorTag - 1;

    constexpr bool is_leaf() const { return bits != kInteriorTag; }
    constexpr uint32_t left() const {
        assert(!is_leaf());
        return first;
    }
    constexpr uint32_t right() const {
        assert(!is_leaf());
        return first + 1;
    }
    constexpr uint32_t count() const {
        assert(is_leaf());
        return bits;
    }
    Box box() const { return {lo, hi}; }

    static BvhNode interior(const Box& b, uint32_t left) {
        BvhNode n{};
        n.lo = b.lo;
        n.hi = b.hi;
        n.first = left;
        n.bits = kInteriorTag;
        return n;
    }
    static BvhNode leaf(const Box& b, uint32_t first, uint32_t count) {
        assert(count <= kMaxCount);
        BvhNode n{};
        n.lo = b.lo;
        n.hi = b.hi;
        n.first = first;
        n.bits = count;
        return n;
    }
};
static_assert(sizeof(BvhNode) == 32, "BVH nodes must stay 32 bytes");

}  // namespace bsp
