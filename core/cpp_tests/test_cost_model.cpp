// The cost model (cost_model.hpp): known costs worked out by hand, the
// pruning bound against true costs on random candidates, the ^Kd prices.
#include <gtest/gtest.h>

#include <random>

#include "builders/cost_model.hpp"

namespace bsp {
namespace {

// K_d = 1, K_i = 1.5, empty bonus 0.2: the defaults, spelled out so the
// expected values below do not move with them.
BuildOptions costs(bool kd_nodes = false) {
    BuildOptions o;
    o.traversal_cost = 1.0f;
    o.intersect_cost = 1.5f;
    o.empty_bonus = 0.2f;
    o.kd_nodes = kd_nodes;
    o.alpha = 0.1f;
    o.general_cost = 2.0f;
    return o;
}

TEST(CostModel, LeafTestsEveryTriangle) {
    const CostModel m(costs());
    EXPECT_EQ(m.leaf(0), 0.0f);
    EXPECT_EQ(m.leaf(10), 15.0f);
}

TEST(CostModel, SplitOfKnownSides) {
    const CostModel m(costs());
    // 1 + 1.5 (0.25 * 4 + 0.75 * 8) = 1 + 1.5 * 7: exact in float.
    EXPECT_EQ(m.split(m.kd_step(), 0.25f, 4, 0.75f, 8), 11.5f);
    EXPECT_EQ(m.split(m.kd_step(), 0.25, 4, 0.75, 8), 11.5f);
    // One side empty: (1 + 1.5 * 0.5 * 10) * (1 - 0.2).
    EXPECT_FLOAT_EQ(m.split(m.kd_step(), 0.5f, 0, 0.5f, 10), 8.5f * 0.8f);
    EXPECT_FLOAT_EQ(m.split(m.kd_step(), 0.5, 10, 0.5, 0), 8.5f * 0.8f);
    // A split that tests as much as the leaf costs more than the leaf.
    EXPECT_GT(m.split(m.kd_step(), 1.0f, 10, 1.0f, 10), m.leaf(10));
}

TEST(CostModel, StepsWithoutKdAreAllAlike) {
    const CostModel m(costs(false));
    EXPECT_EQ(m.step(true, 100), 1.0f);
    EXPECT_EQ(m.step(false, 100), 1.0f);
    EXPECT_FALSE(m.has_fallback(false));
    EXPECT_FALSE(m.has_fallback(true));
}

TEST(CostModel, KdGeneralStepFollowsIze) {
    const CostModel m(costs(true));
    EXPECT_EQ(m.step(true, 11), 1.0f);
    // alpha K_i (n - 1) + K_d = 0.1 * 1.5 * 10 + 1.
    EXPECT_FLOAT_EQ(m.step(false, 11), 2.5f);
    EXPECT_FLOAT_EQ(m.step(false, 1), 1.0f);  // one reference: nothing to save
    EXPECT_TRUE(m.has_fallback(false));
    EXPECT_FALSE(m.has_fallback(true));
    EXPECT_EQ(m.fallback_step(), 2.0f);
    // The fallback prices the same sides at the constant step.
    EXPECT_EQ(m.split(m.fallback_step(), 0.25f, 4, 0.75f, 8), 12.5f);
}

TEST(CostModel, LowerBoundNeverExceedsTrueCost) {
    // Any split whose parts hold at least n_below and n_above references,
    // entered with probabilities summing to at least one (the parts'
    // surfaces cover the parent's), costs at least the bound. The products
    // round, so the bound may exceed the cost by float rounding at most.
    std::mt19937 gen(3);
    std::uniform_int_distribution<uint32_t> count(0, 200), planar(0, 5);
    std::uniform_real_distribution<double> p(0.0, 1.0), extra(0.0, 0.5);
    for (bool kd_nodes : {false, true}) {
        const CostModel m(costs(kd_nodes));
        for (int i = 0; i < 20000; ++i) {
            const uint32_t nb = count(gen), na = count(gen), np = planar(gen);
            const double pb = p(gen), pa = 1.0 - pb + extra(gen);
            const bool kd = gen() % 2;
            const size_t n = size_t(nb) + na + np + 1;
            const float step = i % 3 == 0 && m.has_fallback(kd) ? m.fallback_step() : m.step(kd, n);
            const float bound = m.lower_bound(step, nb, na);
            const float planar_below = m.split(step, pb, nb + np, pa, na);
            const float planar_above = m.split(step, float(pb), nb, float(pa), na + np);
            EXPECT_LE(bound, planar_below * (1.0f + 1e-6f)) << nb << " " << na << " " << pb;
            EXPECT_LE(bound, planar_above * (1.0f + 1e-6f)) << nb << " " << na << " " << pb;
        }
    }
}

TEST(CostModel, LowerBoundIsTightForHalves) {
    // Two halves of equal probability 1/2 hold n each: the split costs
    // exactly step + K_i n, which is the bound.
    const CostModel m(costs());
    EXPECT_EQ(m.lower_bound(m.kd_step(), 6, 6), m.split(m.kd_step(), 0.5f, 6, 0.5f, 6));
    EXPECT_EQ(m.lower_bound(m.kd_step(), 0, 6), m.split(m.kd_step(), 1.0f, 0, 0.0f, 6));
}

TEST(CostModel, TreeTerms) {
    const CostModel plain(costs(false)), kd(costs(true));
    EXPECT_DOUBLE_EQ(plain.tree_term(0.5, NodeKind::Leaf, 4), 0.5 * 1.5 * 4);
    EXPECT_DOUBLE_EQ(plain.tree_term(0.5, NodeKind::Y, 4), 0.5);
    EXPECT_DOUBLE_EQ(plain.tree_term(0.5, NodeKind::General, 4), 0.5);
    EXPECT_DOUBLE_EQ(kd.tree_term(0.5, NodeKind::General, 4), 1.0);  // at K_d,BSP = 2
    EXPECT_DOUBLE_EQ(kd.tree_term(0.5, NodeKind::X, 4), 0.5);
}

}  // namespace
}  // namespace bsp
