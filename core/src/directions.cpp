#include "directions.hpp"

#include <algorithm>
#include <cmath>
#include <unordered_set>

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

std::vector<Vec3> dop_directions(int k) {
    const std::vector<Vec3> axes = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    const std::vector<Vec3> corners = {{1, 1, 1}, {1, 1, -1}, {1, -1, 1}, {-1, 1, 1}};
    const std::vector<Vec3> edges = {{1, 1, 0}, {1, -1, 0}, {1, 0, 1}, {1, 0, -1}, {0, 1, 1}, {0, 1, -1}};
    std::vector<Vec3> out = axes;
    if (k == 7 || k == 13) out.insert(out.end(), corners.begin(), corners.end());
    if (k == 9 || k == 13) out.insert(out.end(), edges.begin(), edges.end());
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

namespace {

Vec3 random_direction(Rng& rng) {
    // Uniform on the sphere (then folded onto a hemisphere by canonical()).
    const double z = 2.0 * rng.uniform() - 1.0;
    const double phi = 2.0 * M_PI * rng.uniform();
    const double r = std::sqrt(std::max(0.0, 1.0 - z * z));
    return canonical(Vec3(float(r * std::cos(phi)), float(r * std::sin(phi)), float(z)));
}

// Up to `m` distinct positions of [0, n), drawn uniformly without replacement.
std::vector<uint32_t> draw(size_t n, size_t m, Rng& rng) {
    std::vector<uint32_t> picked;
    if (m >= n) {
        for (size_t i = 0; i < n; ++i) picked.push_back(uint32_t(i));
        return picked;
    }
    std::unordered_set<uint32_t> seen;
    while (picked.size() < m) {
        const uint32_t i = uint32_t(rng.below(n));
        if (seen.insert(i).second) picked.push_back(i);
    }
    return picked;
}

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

}  // namespace

void node_directions(const BuildOptions& opt, const std::vector<Vec3>& fixed,
                     const std::vector<Triangle>& triangles, const uint32_t* tris, size_t n,
                     Rng& rng, std::vector<Vec3>& out) {
    out.clear();
    size_t k = size_t(opt.k);
    if (opt.plus_axes || opt.strategy == Strategy::Axes) {
        out = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
        k = k > 3 ? k - 3 : 0;
        if (opt.strategy == Strategy::Axes) k = 0;
    }
    switch (opt.strategy) {
        case Strategy::Axes:
        case Strategy::Ize:
            break;
        case Strategy::Fixed:
            out = fixed;
            break;
        case Strategy::Random:
            for (size_t i = 0; i < k; ++i) out.push_back(random_direction(rng));
            break;
        case Strategy::Normals:
            for (uint32_t i : draw(n, k, rng)) out.push_back(unit_normal(triangles[tris[i]]));
            break;
        case Strategy::Clustered: {
            if (k == 0) break;
            std::vector<Vec3> normals;
            for (uint32_t i : draw(n, size_t(opt.cluster_sample), rng))
                normals.push_back(unit_normal(triangles[tris[i]]));
            for (const Vec3& c : cluster_normals(normals, k, opt.cluster_iterations, rng))
                out.push_back(c);
            break;
        }
    }
    // Equal directions would sweep the same planes twice.
    std::vector<Vec3> unique;
    for (const Vec3& d : out) {
        bool seen = false;
        for (const Vec3& e : unique) seen |= (d.x == e.x && d.y == e.y && d.z == e.z);
        if (!seen) unique.push_back(d);
    }
    out.swap(unique);
}

}  // namespace bsp
