// BSP_wn(+): the normals of K random triangles of the node.
#include "builders/strategies/strategy.hpp"

namespace bsp {
namespace {

class NormalsStrategy final : public DirectionStrategy {
public:
    void directions(const NodeTriangles& node, size_t k, Rng& rng,
                    std::vector<Vec3>& out) const override {
        for (uint32_t i : draw(node.count, k, rng))
            out.push_back(unit_normal(node.all[node.ids[i]]));
    }
};

}  // namespace

std::unique_ptr<DirectionStrategy> make_normals_strategy(const BuildOptions&) {
    return std::make_unique<NormalsStrategy>();
}

}  // namespace bsp
