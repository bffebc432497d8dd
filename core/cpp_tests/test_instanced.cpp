// An instanced scene's core (instanced.hpp): matrices checked and inverted,
// the top level over the instances' boxes, and the trace - an identity
// instance gives its tree's hits bit for bit, a translated and a mirrored
// one the hits of the moved scene, coincident instances the first.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <stdexcept>
#include <string>

#include "instanced.hpp"
#include "registry.hpp"
#include "trace/traverse.hpp"

namespace bsp {
namespace {

// A unit cube's 12 triangles.
std::vector<Triangle> cube() {
    const Vec3 c[8] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0},
                       {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};
    const int f[12][3] = {{0, 2, 1}, {0, 3, 2}, {4, 5, 6}, {4, 6, 7}, {0, 1, 5}, {0, 5, 4},
                          {2, 3, 7}, {2, 7, 6}, {1, 2, 6}, {1, 6, 5}, {0, 4, 7}, {0, 7, 3}};
    std::vector<Triangle> t(12);
    for (int i = 0; i < 12; ++i)
        for (int k = 0; k < 3; ++k) t[i].v[k] = c[f[i][k]];
    return t;
}

std::vector<double> moved(double sx, double sy, double sz, double tx, double ty, double tz) {
    return {sx, 0, 0, tx, 0, sy, 0, ty, 0, 0, sz, tz};
}

struct Hits {
    std::vector<float> t, u, v;
    std::vector<int32_t> prim, instance;
    explicit Hits(size_t n) : t(n), u(n), v(n), prim(n), instance(n) {}
};

// The rays o, d (3 floats each), unbounded: t in [0, inf).
RayBatch unbounded(const std::vector<float>& o, const std::vector<float>& d) {
    static const float tmin = 0.0f, tmax = INFINITY;
    RayBatch rays;
    rays.origins = o.data();
    rays.directions = d.data();
    rays.tmin = &tmin;
    rays.tmax = &tmax;
    rays.count = o.size() / 3;
    return rays;
}

Hits trace(const InstancedScene& s, const std::vector<float>& o, const std::vector<float>& d) {
    Hits h(o.size() / 3);
    HitBatch hits{h.t.data(), h.prim.data(), h.u.data(), h.v.data()};
    InstanceHits extra{h.instance.data()};
    intersect_instanced(s, unbounded(o, d), hits, extra, 1);
    return h;
}

// The same rays through one tree (instance stays 0).
Hits trace(const Tree& tree, const std::vector<float>& o, const std::vector<float>& d) {
    Hits h(o.size() / 3);
    HitBatch hits{h.t.data(), h.prim.data(), h.u.data(), h.v.data()};
    intersect(tree, unbounded(o, d), hits, 1, false);
    return h;
}

void random_rays(size_t n, std::vector<float>& o, std::vector<float>& d, float spread) {
    std::mt19937 rng(5);
    std::uniform_real_distribution<float> u(-spread, spread), dir(-1, 1);
    for (size_t i = 0; i < n; ++i) {
        const float x = u(rng), y = u(rng);
        o.insert(o.end(), {x, y, 10.0f});
        d.insert(d.end(), {0.1f * dir(rng), 0.1f * dir(rng), -1.0f});
    }
}

TEST(Instanced, SingularAndBadMatricesAreRefusedByInstance) {
    const Tree tree = build("kd", cube(), {}, nullptr);
    std::vector<double> m = moved(1, 1, 1, 0, 0, 0);
    const std::vector<double> flat = moved(1, 0, 1, 0, 0, 0);
    std::vector<double> two(m);
    two.insert(two.end(), flat.begin(), flat.end());
    try {
        build_instanced({&tree}, {0, 0}, two, {}, nullptr);
        FAIL() << "a singular matrix was accepted";
    } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find("instance 1: its matrix is singular"), std::string::npos)
            << e.what();
    }
    m[3] = NAN;
    EXPECT_THROW(build_instanced({&tree}, {0}, m, {}, nullptr), std::invalid_argument);
    EXPECT_THROW(build_instanced({&tree}, {1}, moved(1, 1, 1, 0, 0, 0), {}, nullptr),
                 std::invalid_argument);
    // The check alone: the same refusal, naming the same instance.
    try {
        check_instance_matrices(two);
        FAIL() << "check_instance_matrices accepted a singular matrix";
    } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find("instance 1: its matrix is singular"), std::string::npos)
            << e.what();
    }
    EXPECT_NO_THROW(check_instance_matrices(moved(2, -1, 0.5, 3, 4, 5)));
    EXPECT_THROW(check_instance_matrices(m), std::invalid_argument);  // the NaN
}

TEST(Instanced, IdentityInstanceTracesAsItsTree) {
    const Tree tree = build("bvh", cube(), {}, nullptr);
    const InstancedScene s = build_instanced({&tree}, {0}, moved(1, 1, 1, 0, 0, 0), {}, nullptr);
    EXPECT_EQ(s.stats.instances, 1u);
    EXPECT_EQ(s.stats.top_nodes, 1u);
    std::vector<float> o, d;
    random_rays(2000, o, d, 2.0f);
    const Hits h = trace(s, o, d);
    const Hits f = trace(tree, o, d);
    const std::vector<int32_t>& prim = f.prim;
    const std::vector<float>& t = f.t;
    const std::vector<float>& u = f.u;
    int hits = 0;
    for (size_t i = 0; i < 2000; ++i) {
        EXPECT_EQ(h.prim[i], prim[i]);
        EXPECT_EQ(h.t[i], t[i]);
        EXPECT_EQ(h.u[i], u[i]);
        EXPECT_EQ(h.instance[i], prim[i] >= 0 ? 0 : -1);
        hits += prim[i] >= 0;
    }
    EXPECT_GT(hits, 100);
}

TEST(Instanced, MovedAndMirroredInstancesAreHitWhereTheyAre) {
    const Tree tree = build("kd", cube(), {}, nullptr);
    std::vector<double> m = moved(1, 1, 1, 5, 0, 0);      // [5, 6] x [0, 1] x [0, 1]
    const std::vector<double> mirror = moved(-2, 1, 0.5, 0, 0, 0);  // [-2, 0] x [0, 1] x [0, 0.5]
    m.insert(m.end(), mirror.begin(), mirror.end());
    const InstancedScene s = build_instanced({&tree}, {0, 0}, m, {}, nullptr);
    // Straight down onto each: the top face's distance.
    const std::vector<float> o = {5.5f, 0.5f, 10.0f, -1.0f, 0.5f, 10.0f, 3.0f, 0.5f, 10.0f};
    const std::vector<float> d = {0, 0, -1, 0, 0, -1, 0, 0, -1};
    const Hits h = trace(s, o, d);
    EXPECT_EQ(h.instance[0], 0);
    EXPECT_FLOAT_EQ(h.t[0], 9.0f);
    EXPECT_EQ(h.instance[1], 1);
    EXPECT_FLOAT_EQ(h.t[1], 9.5f);
    EXPECT_EQ(h.instance[2], -1);
    EXPECT_EQ(h.prim[2], -1);
    EXPECT_TRUE(std::isinf(h.t[2]));
}

TEST(Instanced, OfCoincidentInstancesTheFirstWins) {
    const Tree tree = build("kd", cube(), {}, nullptr);
    std::vector<double> m;
    for (int i = 0; i < 4; ++i) {
        const std::vector<double> one = moved(1, 1, 1, 0, 0, 0);
        m.insert(m.end(), one.begin(), one.end());
    }
    const InstancedScene s = build_instanced({&tree}, {0, 0, 0, 0}, m, {}, nullptr);
    std::vector<float> o, d;
    random_rays(500, o, d, 1.5f);
    const Hits h = trace(s, o, d);
    int hits = 0;
    for (size_t i = 0; i < 500; ++i) {
        if (h.prim[i] < 0) continue;
        ++hits;
        EXPECT_EQ(h.instance[i], 0);
    }
    EXPECT_GT(hits, 20);
    EXPECT_EQ(s.flat_offset[3], 36u);
    EXPECT_EQ(s.stats.instanced_triangles, 48u);
}

}  // namespace
}  // namespace bsp
