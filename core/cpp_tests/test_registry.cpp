// The registry (registry.hpp): what Python cannot reach - the strategy
// table's refusal of an unknown name - and that build() dispatches to the
// method's builder with the method's options.
#include <gtest/gtest.h>

#include <algorithm>
#include <stdexcept>
#include <string>
#include <vector>

#include "builders/strategies/strategy.hpp"
#include "registry.hpp"

namespace bsp {
namespace {

std::string message_of(void (*f)()) {
    try {
        f();
    } catch (const std::invalid_argument& e) {
        return e.what();
    }
    return "";
}

TEST(Registry, UnknownStrategyIsNamedWithTheKnownOnes) {
    const std::string m = message_of([] {
        BuildOptions o;
        o.strategy = "x_only";
        make_strategy(o);
    });
    EXPECT_EQ(m.rfind("unknown direction strategy x_only; known: axes, fixed, random", 0), 0u) << m;
}

TEST(Registry, UnknownMethodIsNamedWithTheKnownOnes) {
    const std::string m = message_of([] { build("octree", {}, {}, nullptr); });
    EXPECT_EQ(m.rfind("unknown method octree; known: kd, rbsp", 0), 0u) << m;
}

TEST(Registry, EveryMethodsStrategyIsInTheTable) {
    const std::vector<std::string> names = strategy_names();
    for (const MethodSpec& m : method_specs()) {
        EXPECT_NE(std::find(names.begin(), names.end(), m.strategy), names.end()) << m.name;
        EXPECT_NE(m.builder.build, nullptr) << m.name;
    }
}

// Two triangles of a unit square: enough for one split.
std::vector<Triangle> square() {
    return {Triangle{{Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(1, 1, 0)}},
            Triangle{{Vec3(0, 0, 0), Vec3(1, 1, 0), Vec3(0, 1, 0)}}};
}

TEST(Registry, BuildRunsTheMethodsBuilderWithItsOptions) {
    for (const MethodSpec& m : method_specs()) {
        const Tree t = build(m.name, square(), {{"leaf_size", int64_t(1)}}, nullptr);
        EXPECT_EQ(t.options.strategy, m.strategy) << m.name;
        EXPECT_EQ(t.options.kd_nodes, m.kd_nodes) << m.name;
        EXPECT_EQ(t.options.leaf_size, 1) << m.name;
        EXPECT_EQ(t.stats.triangles, 2u) << m.name;
        if (m.all_general_nodes()) {
            EXPECT_EQ(t.stats.kd_nodes, 0u) << m.name;
        }
    }
}

}  // namespace
}  // namespace bsp
