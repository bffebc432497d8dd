// The interface of a direction strategy: which plane normals the BSP_SWEEP
// builder sweeps at a node. One strategy per file in this folder; each is
// listed once in strategy_table.cpp (kStrategies), which is how the builder
// finds it by the name in BuildOptions::strategy.
#pragma once
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "builders/strategies/directions.hpp"

namespace bsp {

// The node a strategy picks directions for: its triangles, by index.
struct NodeTriangles {
    const std::vector<Triangle>& all;
    const uint32_t* ids;
    size_t count;
};

class DirectionStrategy {
public:
    virtual ~DirectionStrategy() = default;

    // The node's directions. On entry `out` holds the three axes for "+"
    // methods (BuildOptions::plus_axes) and is empty otherwise; `k` is how
    // many more directions the method asks for. A strategy appends to `out`
    // or replaces it; duplicates are removed afterwards. All randomness must
    // come from `rng`, which is seeded per node, so that trees never depend
    // on the number of threads.
    virtual void directions(const NodeTriangles& node, size_t k, Rng& rng,
                            std::vector<Vec3>& out) const = 0;

    // True when the builder should also try each triangle's own plane and
    // the planes through its edges (BSP_IZE), which are not swept.
    virtual bool tries_triangle_planes() const { return false; }
};

// Made once per tree, from the tree's options (e.g. RBSP's fixed set).
using StrategyFactory = std::unique_ptr<DirectionStrategy> (*)(const BuildOptions&);

// The names of the direction strategies (strategy_table.cpp), and the one a
// tree's options name (std::invalid_argument naming the known ones).
std::vector<std::string> strategy_names();
std::unique_ptr<DirectionStrategy> make_strategy(const BuildOptions& options);

}  // namespace bsp
