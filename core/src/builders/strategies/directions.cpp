#include "builders/strategies/directions.hpp"

#include <algorithm>
#include <cmath>
#include <unordered_set>

#include "builders/strategies/strategy.hpp"

namespace bsp {

Vec3 canonical(Vec3 d) {
    const double len = std::sqrt(double(d.x) * d.x + double(d.y) * d.y + double(d.z) * d.z);
    Vec3 u(float(d.x / len), float(d.y / len), float(d.z / len));
    int big = 0;
    for (int i = 1; i < 3; ++i)
        if (std::fabs(u[i]) > std::fabs(u[big])) big = i;
    if (u[big] < 0) u = u * -1.0f;
    int axis;
    if (is_axis(u, axis)) u = Vec3(float(axis == 0), float(axis == 1), float(axis == 2));
    return u;
}

bool is_axis(const Vec3& d, int& axis) {
    const int zeros = (d.x == 0.0f) + (d.y == 0.0f) + (d.z == 0.0f);
    if (zeros != 2) return false;
    axis = d.x != 0.0f ? 0 : (d.y != 0.0f ? 1 : 2);
    return true;
}

Vec3 unit_normal(const Triangle& t) {
    // In double: a live sliver's float cross product can be zero.
    double n[3];
    t.normal_double(n);
    const double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    return canonical(Vec3(float(n[0] / len), float(n[1] / len), float(n[2] / len)));
}

std::vector<uint32_t> draw(size_t n, size_t m, Rng& rng) {
    std::vector<uint32_t> picked;
    picked.reserve(std::min(n, m));
    if (m >= n) {
        for (size_t i = 0; i < n; ++i) picked.push_back(uint32_t(i));
        return picked;
    }
    // A node draws a few directions' triangles (K at most 64): looking them
    // up among those picked is cheaper than a hash set, made per node. The
    // draws, and so the picks, are the same either way.
    constexpr size_t kScanPicks = 64;
    if (m <= kScanPicks) {
        while (picked.size() < m) {
            const uint32_t i = uint32_t(rng.below(n));
            if (std::find(picked.begin(), picked.end(), i) == picked.end()) picked.push_back(i);
        }
        return picked;
    }
    std::unordered_set<uint32_t> seen;
    while (picked.size() < m) {
        const uint32_t i = uint32_t(rng.below(n));
        if (seen.insert(i).second) picked.push_back(i);
    }
    return picked;
}

void node_directions(const DirectionStrategy& strategy, const BuildOptions& opt,
                     const std::vector<Triangle>& triangles, const uint32_t* tris, size_t n,
                     Rng& rng, std::vector<Vec3>& out) {
    out.clear();
    out.reserve(size_t(opt.k) + 3);
    size_t k = size_t(opt.k);
    if (opt.plus_axes) {
        out.push_back({1, 0, 0});
        out.push_back({0, 1, 0});
        out.push_back({0, 0, 1});
        k = k > 3 ? k - 3 : 0;
    }
    strategy.directions(NodeTriangles{triangles, tris, n}, k, rng, out);
    // Equal directions would sweep the same planes twice: the first of each
    // is kept, in place.
    size_t kept = 0;
    for (size_t i = 0; i < out.size(); ++i) {
        const Vec3 d = out[i];
        bool seen = false;
        for (size_t j = 0; j < kept; ++j)
            seen |= (d.x == out[j].x && d.y == out[j].y && d.z == out[j].z);
        if (!seen) out[kept++] = d;
    }
    out.resize(kept);
}

}  // namespace bsp
