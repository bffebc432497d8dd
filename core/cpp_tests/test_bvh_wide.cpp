// The BVH's 8-wide layout (bvh_wide_node.hpp, builders/bvh_collapse.hpp)
// and its walk (kernels/bvh_wide_single_ray.hpp): the collapse keeps every
// leaf of the binary tree once, with its box, and no deeper than it was;
// the wide walk gives the binary walk's hits bit for bit, on every
// instruction-set level the CPU has.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <map>
#include <random>

#include "builders/bvh_build.hpp"
#include "builders/bvh_collapse.hpp"
#include "trace/cpu_dispatch.hpp"
#include "trace/kernels/kernel_set.hpp"
#include "trace/kernels/tree_view.hpp"
#include "trace/traverse.hpp"

namespace bsp {
namespace {

std::vector<Triangle> random_triangles(size_t n, unsigned seed, float size) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u(-1.0f, 1.0f), s(-size, size);
    std::vector<Triangle> out(n);
    for (Triangle& t : out) {
        const Vec3 c(u(rng), u(rng), u(rng));
        for (Vec3& v : t.v) v = c + Vec3(s(rng), s(rng), s(rng));
    }
    return out;
}

Tree bvh_of(std::vector<Triangle> tris, int leaf_size = 1) {
    BuildOptions o;
    o.leaf_size = leaf_size;
    return build_bvh_tree(std::move(tris), o, nullptr);
}

// Each leaf of the binary tree (by its refs[] offset): its box and depth.
struct LeafInfo {
    Box box;
    uint32_t count;
    int depth;
};

std::map<uint32_t, LeafInfo> binary_leaves(const std::vector<BvhNode>& bin) {
    std::map<uint32_t, LeafInfo> out;
    std::vector<std::pair<uint32_t, int>> stack{{0, 0}};
    while (!stack.empty()) {
        const auto [i, d] = stack.back();
        stack.pop_back();
        if (bin[i].is_leaf()) {
            out[bin[i].first] = {bin[i].box(), bin[i].count(), d};
            continue;
        }
        stack.push_back({bin[i].left(), d + 1});
        stack.push_back({bin[i].right(), d + 1});
    }
    return out;
}

bool same_box(const Box& a, const Box& b) {
    return std::memcmp(&a, &b, sizeof(Box)) == 0;
}

TEST(BvhWide, EveryBinaryLeafOnceWithItsBox) {
    for (const int leaf_size : {1, 8}) {
        const Tree t = bvh_of(random_triangles(20000, 1, 0.02f), leaf_size);
        const std::vector<BvhWideNode> wide = collapse_bvh(t.bvh_nodes);
        ASSERT_EQ(wide.size(), t.bvh_wide.size());
        ASSERT_EQ(0, std::memcmp(wide.data(), t.bvh_wide.data(), wide.size() * sizeof(BvhWideNode)));
        const auto leaves = binary_leaves(t.bvh_nodes);
        std::map<uint32_t, int> seen;
        uint64_t lanes = 0;
        std::vector<std::pair<uint32_t, int>> stack{{0, 0}};
        while (!stack.empty()) {
            const auto [i, d] = stack.back();
            stack.pop_back();
            ASSERT_LT(i, wide.size());
            int used = 0;
            for (int l = 0; l < BvhWideNode::kWidth; ++l) {
                const BvhWideNode& n = wide[i];
                if (n.box(l).empty()) {  // an unused lane: a leaf of nothing
                    EXPECT_TRUE(n.is_leaf(l));
                    EXPECT_EQ(n.leaf_count(l), 0u);
                    continue;
                }
                ++used;
                if (!n.is_leaf(l)) {
                    EXPECT_GT(n.node(l), i);  // depth-first: children after parents
                    stack.push_back({n.node(l), d + 1});
                    continue;
                }
                const auto it = leaves.find(n.first(l));
                ASSERT_NE(it, leaves.end());
                EXPECT_EQ(it->second.count, n.leaf_count(l));
                EXPECT_TRUE(same_box(it->second.box, n.box(l)));
                EXPECT_LE(d + 1, it->second.depth);  // never deeper than in the binary tree
                ++seen[n.first(l)];
            }
            EXPECT_GE(used, 2);
            lanes += uint64_t(used);
        }
        EXPECT_EQ(seen.size(), leaves.size());
        for (const auto& [first, times] : seen) EXPECT_EQ(times, 1) << first;
        // Greedy collapse of a SAH tree fills most lanes: fewer wide nodes than
        // a quarter of the binary interior nodes, more than half the lanes used.
        constexpr int W = BvhWideNode::kWidth;
        EXPECT_LT(wide.size(), (t.bvh_nodes.size() - leaves.size()) / (W / 2));
        EXPECT_GT(double(lanes) / double(wide.size()), 0.5 * W);
    }
}

TEST(BvhWide, OneLeafAndEmptyTrees) {
    const Tree one = bvh_of(random_triangles(1, 2, 0.1f));
    ASSERT_EQ(one.bvh_wide.size(), 1u);
    EXPECT_TRUE(one.bvh_wide[0].is_leaf(0));
    EXPECT_EQ(one.bvh_wide[0].leaf_count(0), 1u);
    for (int l = 1; l < BvhWideNode::kWidth; ++l) EXPECT_TRUE(one.bvh_wide[0].box(l).empty());
    const Tree none = bvh_of({});
    ASSERT_EQ(none.bvh_wide.size(), 1u);
    EXPECT_EQ(none.bvh_wide[0].leaf_count(0), 0u);
    EXPECT_TRUE(none.bvh_wide[0].box(0).empty());
}

// Hits of the binary and the wide walk, hits only, through the kernel sets
// the CPU can run.
TEST(BvhWide, SameHitsAsTheBinaryWalkBitForBit) {
    // A few triangles too: a wide root whose lane 0 is a leaf, not the whole tree.
    for (const auto& [count, size] : {std::pair{3000, 0.05f}, {3000, 0.3f}, {3, 0.8f}, {1, 0.8f}}) {
        const Tree t = bvh_of(random_triangles(size_t(count), 3, size), count > 3 ? 4 : 1);
        std::mt19937 rng(7);
        std::uniform_real_distribution<float> u(-1.5f, 1.5f);
        const size_t n = 4000;
        std::vector<float> o(3 * n), d(3 * n), tmin(1, 0.0f), tmax(n);
        for (size_t i = 0; i < n; ++i) {
            for (int k = 0; k < 3; ++k) {
                o[3 * i + k] = u(rng);
                d[3 * i + k] = u(rng);
            }
            if (i % 5 == 0) d[3 * i + int(i / 5 % 3)] = 0.0f;  // axis-parallel in one axis
            if (i % 7 == 0) o[3 * i] = 1e4f;                     // from far outside
            tmax[i] = i % 3 == 0 ? 0.7f : INFINITY;              // short segments too
        }
        RayBatch rays;
        rays.origins = o.data();
        rays.directions = d.data();
        rays.tmin = tmin.data();
        rays.tmax = tmax.data();
        rays.tmax_stride = 1;
        rays.count = n;
        const TreeView view = make_tree_view(t);
        const KernelSet& k = selected_kernels();
        std::vector<float> t0(n), u0(n), v0(n), t1(n), u1(n), v1(n);
        std::vector<int32_t> p0(n), p1(n);
        HitBatch a{t0.data(), p0.data(), u0.data(), v0.data()};
        HitBatch b{t1.data(), p1.data(), u1.data(), v1.data()};
        k.bvh_binary_hits(view, rays, a, 0, n);
        k.bvh_single_ray[0](view, rays, b, 0, n);
        size_t hits = 0;
        for (size_t i = 0; i < n; ++i) {
            ASSERT_EQ(p0[i], p1[i]) << "ray " << i;
            ASSERT_EQ(std::memcmp(&t0[i], &t1[i], 4), 0) << "ray " << i;
            ASSERT_EQ(std::memcmp(&u0[i], &u1[i], 4), 0) << "ray " << i;
            ASSERT_EQ(std::memcmp(&v0[i], &v1[i], 4), 0) << "ray " << i;
            hits += p0[i] >= 0;
        }
        EXPECT_GT(hits, count > 3 ? n / 20 : 20u);  // the rays do hit
    }
}

}  // namespace
}  // namespace bsp
