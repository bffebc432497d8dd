// The BVH's node encoding (BvhNode, bvh_node.hpp) and its builder's core
// (build_bvh, builders/bvh_build.hpp) over plain boxes, as the instanced
// scenes' top level will call it: structure, tight boxes, determinism over
// threads, the leaf rule, the memory budget and cancel.
#include <gtest/gtest.h>

#include <random>
#include <cstring>
#include <set>

#include "builders/bvh_build.hpp"
#include "builders/memory.hpp"
#include "progress.hpp"

namespace bsp {
namespace {

Box box_of(float x0, float y0, float z0, float x1, float y1, float z1) {
    Box b;
    b.extend(Vec3(x0, y0, z0));
    b.extend(Vec3(x1, y1, z1));
    return b;
}

TEST(BvhNode, RoundTrip) {
    const Box b = box_of(-1, -2, -3, 4, 5, 6);
    const BvhNode in = BvhNode::interior(b, 7);
    EXPECT_FALSE(in.is_leaf());
    EXPECT_EQ(in.left(), 7u);
    EXPECT_EQ(in.right(), 8u);
    EXPECT_EQ(in.lo.y, -2.0f);
    EXPECT_EQ(in.hi.z, 6.0f);
    for (uint32_t count : {0u, 1u, 16u, BvhNode::kMaxCount}) {
        const BvhNode leaf = BvhNode::leaf(b, 123, count);
        EXPECT_TRUE(leaf.is_leaf());
        EXPECT_EQ(leaf.count(), count);
        EXPECT_EQ(leaf.first, 123u);
    }
    EXPECT_EQ(sizeof(BvhNode), 32u);
    EXPECT_EQ(alignof(BvhNode), 32u);
}

#ifndef NDEBUG
TEST(BvhNodeDeath, AccessorsAssertTheKind) {
    const BvhNode leaf = BvhNode::leaf(Box(), 0, 3);
    const BvhNode in = BvhNode::interior(Box(), 1);
    EXPECT_DEATH((void)leaf.left(), "");
    EXPECT_DEATH((void)in.count(), "");
}
#endif

struct Boxes {
    std::vector<Box> boxes;
    std::vector<Vec3> centroids;
    std::vector<uint32_t> ids;
};

Boxes random_boxes(size_t n, unsigned seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u(0.0f, 1.0f), s(0.0f, 0.02f);
    Boxes b;
    for (size_t i = 0; i < n; ++i) {
        const float x = u(rng), y = u(rng), z = u(rng);
        b.boxes.push_back(box_of(x, y, z, x + s(rng), y + s(rng), z + s(rng)));
        b.centroids.push_back((b.boxes.back().lo + b.boxes.back().hi) * 0.5f);
        b.ids.push_back(uint32_t(i));
    }
    return b;
}

bool contains(const Box& outer, const Box& inner) {
    for (int k = 0; k < 3; ++k)
        if (inner.lo[k] < outer.lo[k] || inner.hi[k] > outer.hi[k]) return false;
    return true;
}

BvhResult build(const Boxes& b, BvhSettings s, double limit_mb = 1024, Progress* p = nullptr) {
    MemoryBudget budget(limit_mb);
    return build_bvh(b.boxes, b.centroids, b.ids, s, p, budget);
}

TEST(BvhBuild, EveryPrimitiveOnceInATightLeaf) {
    const Boxes b = random_boxes(5000, 1);
    const BvhResult r = build(b, BvhSettings{});
    ASSERT_EQ(r.order.size(), b.ids.size());
    EXPECT_EQ(std::set<uint32_t>(r.order.begin(), r.order.end()).size(), b.ids.size());
    EXPECT_EQ(r.nodes.size(), 2 * r.leaves - 1);
    uint64_t in_leaves = 0;
    for (const BvhNode& n : r.nodes) {
        if (!n.is_leaf()) {
            ASSERT_LT(n.right(), r.nodes.size());
            EXPECT_TRUE(contains(n.box(), r.nodes[n.left()].box()));
            EXPECT_TRUE(contains(n.box(), r.nodes[n.right()].box()));
            continue;
        }
        EXPECT_GE(n.count(), 1u);
        EXPECT_LE(n.count(), kBvhMaxLeaf);
        Box tight;
        for (uint32_t i = 0; i < n.count(); ++i) tight.extend(b.boxes[r.order[n.first + i]]);
        EXPECT_EQ(tight.lo.x, n.lo.x);
        EXPECT_EQ(tight.hi.z, n.hi.z);
        in_leaves += n.count();
    }
    EXPECT_EQ(in_leaves, b.ids.size());
    EXPECT_GT(r.sah_cost, 0.0);
}

TEST(BvhBuild, SameNodesOnAnyThreadCount) {
    const Boxes b = random_boxes(100000, 2);  // parallel binning and spawned subtrees
    BvhSettings one;
    one.threads = 1;
    const BvhResult a = build(b, one);
    for (int threads : {2, 4}) {
        BvhSettings many;
        many.threads = threads;
        const BvhResult c = build(b, many);
        ASSERT_EQ(a.nodes.size(), c.nodes.size());
        EXPECT_EQ(0, std::memcmp(a.nodes.data(), c.nodes.data(), a.nodes.size() * sizeof(BvhNode)));
        EXPECT_EQ(a.order, c.order);
        EXPECT_EQ(a.sah_cost, c.sah_cost);
    }
}

TEST(BvhBuild, CoincidentCentroidsAreHalvedBeyondTheLeafLimit) {
    Boxes b;
    for (uint32_t i = 0; i < 100; ++i) {
        b.boxes.push_back(box_of(0, 0, 0, 1, 1, 1));
        b.centroids.push_back(Vec3(0.5f, 0.5f, 0.5f));
        b.ids.push_back(i);
    }
    const BvhResult r = build(b, BvhSettings{});
    EXPECT_EQ(r.max_leaf_size, kBvhMaxLeaf >= 100 ? 100u : r.max_leaf_size);
    EXPECT_LE(r.max_leaf_size, uint64_t(kBvhMaxLeaf));
    EXPECT_GT(r.leaves, 1u);
}

TEST(BvhBuild, LeafSizeAndDepthLimit) {
    const Boxes b = random_boxes(2000, 3);
    BvhSettings s;
    s.leaf_size = 64;  // nodes of at most 64 stay leaves
    const BvhResult big = build(b, s);
    EXPECT_GE(big.max_leaf_size, 17u);
    s = BvhSettings{};
    s.depth_limit = 4;
    const BvhResult shallow = build(b, s);
    EXPECT_LE(shallow.max_depth, 4);
    EXPECT_LE(shallow.leaves, 16u);
}

TEST(BvhBuild, EmptyInputIsOneEmptyLeaf) {
    const Boxes b;
    const BvhResult r = build(b, BvhSettings{});
    ASSERT_EQ(r.nodes.size(), 1u);
    EXPECT_TRUE(r.nodes[0].is_leaf());
    EXPECT_EQ(r.nodes[0].count(), 0u);
    EXPECT_TRUE(r.nodes[0].box().empty());
}

TEST(BvhBuild, MemoryLimitAndCancel) {
    const Boxes b = random_boxes(50000, 4);
    EXPECT_THROW(build(b, BvhSettings{}, 0.5), MemoryLimitExceeded);
    Progress p;
    p.cancel();
    EXPECT_THROW(build(b, BvhSettings{}, 1024, &p), Cancelled);
    Progress done;
    build(b, BvhSettings{}, 1024, &done);
    EXPECT_DOUBLE_EQ(done.value(), 1.0);
}

}  // namespace
}  // namespace bsp
