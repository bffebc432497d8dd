// kd: the three coordinate axes at every node, nothing else.
#include "builders/strategies/strategy.hpp"

namespace bsp {
namespace {

class AxesStrategy final : public DirectionStrategy {
public:
    void directions(const NodeTriangles&, size_t, Rng&, std::vector<Vec3>& out) const override {
        // Replaces rather than appends: the axes whether or not plus_axes
        // already put them there.
        out = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    }
};

}  // namespace

std::unique_ptr<DirectionStrategy> make_axes_strategy(const BuildOptions&) {
    return std::make_unique<AxesStrategy>();
}

}  // namespace bsp
