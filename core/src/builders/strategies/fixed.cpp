// RBSP: one fixed set of K directions for the whole tree, chosen by
// BuildOptions::fixed_set: 0 golden-spiral points on the hemisphere, 1 the
// k-DOP directions (coordinates in {-1, 0, 1}, K = 3, 7, 9, 13), 2 the three
// axes plus K - 3 spiral points (so that RBSP^Kd has kd nodes for any K >= 3).
#include <algorithm>
#include <cmath>

#include "builders/strategies/strategy.hpp"

namespace bsp {
namespace {

std::vector<Vec3> spiral_directions(int k) {
    // Points spread evenly over the upper hemisphere: equal-area rings in z,
    // successive points turned by the golden angle.
    std::vector<Vec3> out;
    const double golden = M_PI * (3.0 - std::sqrt(5.0));
    for (int i = 0; i < k; ++i) {
        const double z = 1.0 - (i + 0.5) / k;
        const double r = std::sqrt(std::max(0.0, 1.0 - z * z));
        const double phi = golden * i;
        out.push_back(canonical(Vec3(float(r * std::cos(phi)), float(r * std::sin(phi)), float(z))));
    }
    return out;
}

// Empty when K is not 3, 7, 9 or 13 (the Python checks refuse those first).
std::vector<Vec3> dop_directions(int k) {
    const std::vector<Vec3> axes = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    const std::vector<Vec3> corners = {{1, 1, 1}, {1, 1, -1}, {1, -1, 1}, {-1, 1, 1}};
    const std::vector<Vec3> edges = {{1, 1, 0}, {1, -1, 0}, {1, 0, 1}, {1, 0, -1}, {0, 1, 1}, {0, 1, -1}};
    std::vector<Vec3> out = axes;
    // (Loops rather than insert(): GCC 12 warns falsely of an overflow there.)
    if (k == 7 || k == 13)
        for (const Vec3& d : corners) out.push_back(d);
    if (k == 9 || k == 13)
        for (const Vec3& d : edges) out.push_back(d);
    if (k != 3 && k != 7 && k != 9 && k != 13) return {};
    for (Vec3& d : out) d = canonical(d);
    return out;
}

std::vector<Vec3> fixed_directions(int set, int k) {
    if (set == 1) return dop_directions(k);
    if (set == 0 || k <= 3) return spiral_directions(k);
    std::vector<Vec3> out = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    for (const Vec3& d : spiral_directions(k - 3)) out.push_back(d);
    return out;
}

class FixedStrategy final : public DirectionStrategy {
public:
    explicit FixedStrategy(std::vector<Vec3> set) : set_(std::move(set)) {}
    void directions(const NodeTriangles&, size_t, Rng&, std::vector<Vec3>& out) const override {
        // The set is the whole of K (set 2 holds the axes itself).
        out = set_;
    }

private:
    std::vector<Vec3> set_;
};

}  // namespace

std::unique_ptr<DirectionStrategy> make_fixed_strategy(const BuildOptions& opt) {
    return std::make_unique<FixedStrategy>(fixed_directions(opt.fixed_set, opt.k));
}

}  // namespace bsp
