// Shared helpers of the direction strategies (strategies/*.cpp): the random
// generator, canonical directions, triangle normals, sampling, and the step
// every node takes (node_directions). All randomness comes from a per-node
// generator seeded by the build seed and the node's position in the tree, so
// trees never depend on threads.
#pragma once
#include <cstdint>
#include <vector>

#include "geometry.hpp"
#include "tree.hpp"

namespace bsp {

// splitmix64: small, fast, and good enough to draw directions and triangles.
class Rng {
public:
    explicit Rng(uint64_t seed) : state_(seed) {}
    uint64_t next() {
        uint64_t z = (state_ += 0x9E3779B97F4A7C15ull);
        z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
        z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
        return z ^ (z >> 31);
    }
    double uniform() { return double(next() >> 11) * (1.0 / 9007199254740992.0); }
    uint64_t below(uint64_t n) { return next() % n; }  // n is small: the bias is negligible
    static uint64_t mix(uint64_t a, uint64_t b) { return Rng(a * 0x9E3779B97F4A7C15ull ^ b).next(); }

private:
    uint64_t state_;
};

// A direction and its negation give the same planes: keep one, with its
// largest component positive. Axis directions come out exactly as (1,0,0)...
Vec3 canonical(Vec3 d);
bool is_axis(const Vec3& d, int& axis);
Vec3 unit_normal(const Triangle& t);

// Up to `m` distinct positions of [0, n), drawn uniformly without replacement.
std::vector<uint32_t> draw(size_t n, size_t m, Rng& rng);

class DirectionStrategy;

// The directions a node sweeps: the three axes first for "+" methods
// (opt.plus_axes, which count them among opt.k), then the strategy's, with
// duplicates removed. `tris` are the node's triangle indices.
void node_directions(const DirectionStrategy& strategy, const BuildOptions& opt,
                     const std::vector<Triangle>& triangles, const uint32_t* tris, size_t n,
                     Rng& rng, std::vector<Vec3>& out);

}  // namespace bsp
