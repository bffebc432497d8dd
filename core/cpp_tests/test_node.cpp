// The 8-byte node encoding (Node in tree.hpp): round trips of every kind at
// the limits of its bit fields, the asserts that guard them, and the kinds of
// the nodes real builds flatten.
#include <gtest/gtest.h>

#include <random>

#include "builders/bsp_build.hpp"
#include "builders/kd_build.hpp"
#include "tree.hpp"

namespace bsp {
namespace {

// The encoders are constexpr: the layout can be checked at compile time.
static_assert(Node::kd(2, 1.5f, 7).kind() == NodeKind::Z);
static_assert(Node::kd(2, 1.5f, 7).kd_above() == 7);
static_assert(Node::leaf(9, 3).count() == 3 && Node::leaf(9, 3).first == 9);
static_assert(Node::general(4, 5).general_above() == 5);
static_assert(Node::general(4, 5).kind() == NodeKind::General);
static_assert(kMaxNodes == (1u << 29) - 1, "29 bits for a general node's child");

TEST(Node, KdRoundTrip) {
    for (int axis = 0; axis < 3; ++axis) {
        for (uint32_t above : {1u, 12345u, Node::kMaxKdChild}) {
            const Node n = Node::kd(axis, -3.25f, above);
            EXPECT_TRUE(n.is_kd());
            EXPECT_FALSE(n.is_leaf());
            EXPECT_FALSE(n.is_general());
            EXPECT_EQ(n.kind(), kd_kind(axis));
            EXPECT_EQ(n.axis(), axis);
            EXPECT_EQ(axis_of(n.kind()), axis);
            EXPECT_EQ(n.kd_above(), above);
            EXPECT_EQ(n.split, -3.25f);
        }
    }
}

TEST(Node, LeafRoundTrip) {
    for (uint32_t count : {0u, 1u, 1000u, Node::kMaxPayload}) {
        const Node n = Node::leaf(0xdeadbeefu, count);
        EXPECT_TRUE(n.is_leaf());
        EXPECT_FALSE(n.is_kd());
        EXPECT_FALSE(n.is_general());
        EXPECT_EQ(n.kind(), NodeKind::Leaf);
        EXPECT_EQ(n.count(), count);
        EXPECT_EQ(n.first, 0xdeadbeefu);
    }
}

TEST(Node, GeneralRoundTrip) {
    for (uint32_t above : {1u, 77u, kMaxNodes}) {
        const Node n = Node::general(42, above);
        EXPECT_TRUE(n.is_general());
        EXPECT_FALSE(n.is_kd());
        EXPECT_FALSE(n.is_leaf());
        EXPECT_EQ(n.kind(), NodeKind::General);
        EXPECT_EQ(n.general_above(), above);
        EXPECT_EQ(n.first, 42u);
    }
}

TEST(Node, KindHelpers) {
    EXPECT_TRUE(is_kd(NodeKind::X) && is_kd(NodeKind::Y) && is_kd(NodeKind::Z));
    EXPECT_FALSE(is_kd(NodeKind::Leaf));
    EXPECT_FALSE(is_kd(NodeKind::General));
    for (int axis = 0; axis < 3; ++axis) EXPECT_EQ(axis_of(kd_kind(axis)), axis);
}

#ifndef NDEBUG
// Out-of-range fields would silently corrupt a neighbour's bits; the asserts
// stop them in debug, sanitizer and these tests' builds.
TEST(NodeDeathTest, EncodersRejectWhatDoesNotFit) {
    GTEST_FLAG_SET(death_test_style, "threadsafe");
    EXPECT_DEATH(Node::leaf(0, Node::kMaxPayload + 1), "count <= kMaxPayload");
    EXPECT_DEATH(Node::general(0, Node::kMaxPayload + 1), "above <= kMaxPayload");
    EXPECT_DEATH(Node::kd(0, 0.0f, Node::kMaxKdChild + 1), "above <= kMaxKdChild");
    EXPECT_DEATH(Node::kd(3, 0.0f, 1), "axis < 3");
    EXPECT_DEATH(kd_kind(-1), "axis >= 0");
}

TEST(NodeDeathTest, DecodersRejectTheWrongKind) {
    GTEST_FLAG_SET(death_test_style, "threadsafe");
    EXPECT_DEATH(Node::leaf(0, 2).axis(), "is_kd");
    EXPECT_DEATH(Node::general(0, 2).kd_above(), "is_kd");
    EXPECT_DEATH(Node::kd(1, 0.0f, 2).count(), "is_leaf");
    EXPECT_DEATH(Node::leaf(0, 2).general_above(), "is_general");
    EXPECT_DEATH(axis_of(NodeKind::General), "is_kd");
}
#endif

// A small random scene, the same on every run.
std::vector<Triangle> scene(int n) {
    std::mt19937 gen(5);
    std::uniform_real_distribution<float> x(0.0f, 10.0f), d(-0.5f, 0.5f);
    std::vector<Triangle> tris;
    for (int i = 0; i < n; ++i) {
        const Vec3 a(x(gen), x(gen), x(gen));
        tris.push_back({{a, a + Vec3(d(gen), d(gen), d(gen)), a + Vec3(d(gen), d(gen), d(gen))}});
    }
    return tris;
}

// Walks a flat tree from the root: every child index stays inside the array,
// the child below follows its parent, and the kinds add up to the stats.
void check_flat_tree(const Tree& t) {
    uint64_t kd = 0, general = 0, leaves = 0;
    std::vector<uint32_t> stack{0};
    while (!stack.empty()) {
        const uint32_t i = stack.back();
        stack.pop_back();
        ASSERT_LT(i, t.nodes.size());
        const Node& n = t.nodes[i];
        switch (n.kind()) {
            case NodeKind::Leaf:
                ++leaves;
                if (n.count() > 1) {
                    EXPECT_LE(n.first + n.count(), t.refs.size());
                }
                continue;
            case NodeKind::General:
                ++general;
                EXPECT_LT(n.first, t.planes.size());
                stack.push_back(n.general_above());
                break;
            default:
                ++kd;
                stack.push_back(n.kd_above());
                break;
        }
        stack.push_back(i + 1);
    }
    EXPECT_EQ(kd, t.stats.kd_nodes);
    EXPECT_EQ(general, t.stats.general_nodes);
    EXPECT_EQ(leaves, t.stats.leaves);
    EXPECT_EQ(kd + general + leaves, t.nodes.size());
}

// Builds over the small scene on one thread; returns the (kd, general) counts.
struct Kinds {
    uint64_t kd, general;
};
Kinds flattened_kinds(bool sweep, bool kd_nodes) {
    BuildOptions o;
    o.threads = 1;
    o.kd_nodes = kd_nodes;
    const Tree t = sweep ? build_bsp_tree(scene(300), o) : build_kd_tree(scene(300), o);
    check_flat_tree(t);
    return {t.stats.kd_nodes, t.stats.general_nodes};
}

TEST(Node, FlattenedTreesHoldTheirBuildersKinds) {
    // The kd builder makes kd nodes only; the sweep over the axes makes
    // general nodes without ^Kd and stores every (axis) split as a kd node
    // with it.
    const Kinds kd = flattened_kinds(false, false);
    EXPECT_GT(kd.kd, 0u);
    EXPECT_EQ(kd.general, 0u);
    const Kinds sweep = flattened_kinds(true, false);
    EXPECT_EQ(sweep.kd, 0u);
    EXPECT_GT(sweep.general, 0u);
    const Kinds sweep_kd = flattened_kinds(true, true);
    EXPECT_GT(sweep_kd.kd, 0u);
    EXPECT_EQ(sweep_kd.general, 0u);
}

}  // namespace
}  // namespace bsp
