// BSP_random(+): K fresh directions, uniform on the sphere, at every node.
#include <algorithm>
#include <cmath>

#include "builders/strategies/strategy.hpp"

namespace bsp {
namespace {

Vec3 random_direction(Rng& rng) {
    // Uniform on the sphere (then folded onto a hemisphere by canonical()).
    const double z = 2.0 * rng.uniform() - 1.0;
    const double phi = 2.0 * M_PI * rng.uniform();
    const double r = std::sqrt(std::max(0.0, 1.0 - z * z));
    return canonical(Vec3(float(r * std::cos(phi)), float(r * std::sin(phi)), float(z)));
}

class RandomStrategy final : public DirectionStrategy {
public:
    void directions(const NodeTriangles&, size_t k, Rng& rng,
                    std::vector<Vec3>& out) const override {
        for (size_t i = 0; i < k; ++i) out.push_back(random_direction(rng));
    }
};

}  // namespace

std::unique_ptr<DirectionStrategy> make_random_strategy(const BuildOptions&) {
    return std::make_unique<RandomStrategy>();
}

}  // namespace bsp
