// BSP_IZE (Ize, Wald & Parker 2008): no swept directions beyond the axes
// ("+"); the builder tries each triangle's own plane and its three edge
// planes instead (BspBuilder::ize_planes in bsp_build.cpp, which needs the
// node's clipped references).
#include "builders/strategies/strategy.hpp"

namespace bsp {
namespace {

class IzeStrategy final : public DirectionStrategy {
public:
    void directions(const NodeTriangles&, size_t, Rng&, std::vector<Vec3>&) const override {}
    bool tries_triangle_planes() const override { return true; }
};

}  // namespace

std::unique_ptr<DirectionStrategy> make_ize_strategy(const BuildOptions&) {
    return std::make_unique<IzeStrategy>();
}

}  // namespace bsp
