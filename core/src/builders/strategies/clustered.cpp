// BSP_cn(+): K cluster centres of the node's normals (at most
// cluster_sample of them, k-means for at most cluster_iterations rounds).
#include <algorithm>
#include <cmath>

#include "builders/strategies/strategy.hpp"

namespace bsp {
namespace {

// Spherical k-means where n and -n are the same plane family: a normal joins
// the centre with the largest |n.c|, and is flipped towards it before the
// centre is averaged, so near-identical planes never split across clusters.
std::vector<Vec3> cluster_normals(const std::vector<Vec3>& normals, size_t k, int rounds,
                                  Rng& rng) {
    std::vector<Vec3> centres;
    for (uint32_t i : draw(normals.size(), k, rng)) centres.push_back(normals[i]);
    std::vector<double> sum(3 * centres.size());
    for (int round = 0; round < rounds; ++round) {
        std::fill(sum.begin(), sum.end(), 0.0);
        for (const Vec3& n : normals) {
            size_t best = 0;
            float best_dot = -1.0f;
            float sign = 1.0f;
            for (size_t c = 0; c < centres.size(); ++c) {
                const float d = dot(n, centres[c]);
                if (std::fabs(d) > best_dot) best_dot = std::fabs(d), best = c, sign = d < 0 ? -1.0f : 1.0f;
            }
            sum[3 * best + 0] += sign * n.x;
            sum[3 * best + 1] += sign * n.y;
            sum[3 * best + 2] += sign * n.z;
        }
        double moved = 0;
        for (size_t c = 0; c < centres.size(); ++c) {
            const double len = std::sqrt(sum[3 * c] * sum[3 * c] + sum[3 * c + 1] * sum[3 * c + 1] +
                                         sum[3 * c + 2] * sum[3 * c + 2]);
            if (len == 0) continue;  // an empty cluster keeps its centre
            const Vec3 next = canonical(Vec3(float(sum[3 * c] / len), float(sum[3 * c + 1] / len),
                                             float(sum[3 * c + 2] / len)));
            moved = std::max(moved, 1.0 - std::fabs(double(dot(next, centres[c]))));
            centres[c] = next;
        }
        if (moved < 1e-3) break;
    }
    return centres;
}

class ClusteredStrategy final : public DirectionStrategy {
public:
    ClusteredStrategy(int sample, int rounds) : sample_(sample), rounds_(rounds) {}
    void directions(const NodeTriangles& node, size_t k, Rng& rng,
                    std::vector<Vec3>& out) const override {
        if (k == 0) return;
        std::vector<Vec3> normals;
        for (uint32_t i : draw(node.count, size_t(sample_), rng))
            normals.push_back(unit_normal(node.all[node.ids[i]]));
        for (const Vec3& c : cluster_normals(normals, k, rounds_, rng)) out.push_back(c);
    }

private:
    int sample_, rounds_;
};

}  // namespace

std::unique_ptr<DirectionStrategy> make_clustered_strategy(const BuildOptions& opt) {
    return std::make_unique<ClusteredStrategy>(opt.cluster_sample, opt.cluster_iterations);
}

}  // namespace bsp
