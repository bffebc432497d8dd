// Incoherent rays in spatial order (trace/ray_order.hpp): the sorted copy
// holds every ray once, with its own limits, neighbours in it are near each
// other, and scatter() puts each hit back at its ray.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <utility>
#include <vector>

#include "trace/ray_order.hpp"

namespace bsp {
namespace {

struct RandomRays {
    std::vector<float> o, d, tmin, tmax;
    RayBatch batch;
    explicit RandomRays(size_t n, uint32_t seed = 1) : o(3 * n), d(3 * n), tmin(n), tmax(n) {
        std::mt19937 g(seed);
        std::uniform_real_distribution<float> u(-1.0f, 1.0f);
        std::normal_distribution<float> normal;
        for (float& x : o) x = 10.0f * u(g);
        for (float& x : d) x = normal(g);
        for (size_t i = 0; i < n; ++i) {
            tmin[i] = float(i);  // each ray's own values, to find them again
            tmax[i] = float(i) + 0.5f;
        }
        batch.origins = o.data();
        batch.directions = d.data();
        batch.tmin = tmin.data();
        batch.tmax = tmax.data();
        batch.tmin_stride = batch.tmax_stride = 1;
        batch.count = n;
    }
};

// Which caller's ray (from begin) a sorted ray is: its tmin says.
size_t source_of(const OrderedRays& ordered, size_t i) {
    return size_t(ordered.rays().tmin[i]);
}

TEST(OrderedRays, HoldsEveryRayOnceWithItsOwnLimits) {
    RandomRays r(40000);
    const size_t begin = 3000, end = 37000;
    const OrderedRays ordered(r.batch, begin, end, 2);
    ASSERT_EQ(ordered.rays().count, end - begin);
    std::vector<int> seen(end, 0);
    for (size_t i = 0; i < end - begin; ++i) {
        const size_t src = source_of(ordered, i);
        ASSERT_GE(src, begin);
        ASSERT_LT(src, end);
        ++seen[src];
        EXPECT_EQ(ordered.rays().tmax[i], r.tmax[src]);
        for (int k = 0; k < 3; ++k) {
            EXPECT_EQ(ordered.rays().origins[3 * i + k], r.o[3 * src + k]);
            EXPECT_EQ(ordered.rays().directions[3 * i + k], r.d[3 * src + k]);
        }
    }
    for (size_t i = begin; i < end; ++i) EXPECT_EQ(seen[i], 1) << i;
}

TEST(OrderedRays, SharedLimitsStayShared) {
    RandomRays r(5000);
    const float lo = 0.25f, hi = 9.0f;
    r.batch.tmin = &lo;
    r.batch.tmax = &hi;
    r.batch.tmin_stride = r.batch.tmax_stride = 0;
    const OrderedRays ordered(r.batch, 0, 5000);
    EXPECT_EQ(ordered.rays().tmin_stride, 0u);
    EXPECT_EQ(ordered.rays().tmax_stride, 0u);
    EXPECT_EQ(ordered.rays().tmin[0], lo);
    EXPECT_EQ(ordered.rays().tmax[0], hi);
}

TEST(OrderedRays, NeighboursAreNearerThanInTheGivenOrder) {
    RandomRays r(50000);
    const OrderedRays ordered(r.batch, 0, 50000);
    const auto mean_gap = [](const float* o, const float* d, size_t n) {
        double sum = 0.0;
        for (size_t i = 0; i + 1 < n; ++i) {
            double od = 0.0, dl = 0.0, dn = 0.0, dot = 0.0;
            for (int k = 0; k < 3; ++k) {
                od += std::pow(double(o[3 * i + k]) - o[3 * i + 3 + k], 2);
                dot += double(d[3 * i + k]) * d[3 * i + 3 + k];
                dl += double(d[3 * i + k]) * d[3 * i + k];
                dn += double(d[3 * i + 3 + k]) * d[3 * i + 3 + k];
            }
            // Origin distance over the box (20 wide) plus the angle's cosine gap.
            sum += std::sqrt(od) / 20.0 + (1.0 - dot / std::sqrt(dl * dn));
        }
        return sum / double(n - 1);
    };
    const double given = mean_gap(r.o.data(), r.d.data(), 50000);
    const double sorted =
        mean_gap(ordered.rays().origins, ordered.rays().directions, ordered.rays().count);
    EXPECT_LT(sorted, 0.5 * given) << given << " " << sorted;
}

// The order itself, pinned: a stable sort of the documented key (ray_order.hpp:
// the origin's cell in the window's origin box and the direction's cell on
// the cube, 32 per axis, interleaved bit by bit, origin x first), computed
// here bit by bit. However the core spreads the bits, the rays must come in
// this order.
TEST(OrderedRays, OrderIsTheStableSortOfTheMortonKey) {
    RandomRays r(30000, 7);
    // A few rays along the axes and at the box's faces, whose cells sit at 0 and 31.
    for (size_t i = 0; i < 300; ++i) {
        r.d[3 * i + 0] = r.d[3 * i + 1] = r.d[3 * i + 2] = 0.0f;
        r.d[3 * i + i % 3] = i % 2 ? 1.0f : -1.0f;
        r.o[3 * (i + 300) + i % 3] = i % 2 ? 10.0f : -10.0f;
    }
    const size_t begin = 2000, end = 29000, n = end - begin;
    float lo[3], hi[3], scale[3];
    for (int k = 0; k < 3; ++k) lo[k] = hi[k] = r.o[3 * begin + k];
    for (size_t i = begin; i < end; ++i)
        for (int k = 0; k < 3; ++k) {
            lo[k] = std::min(lo[k], r.o[3 * i + k]);
            hi[k] = std::max(hi[k], r.o[3 * i + k]);
        }
    for (int k = 0; k < 3; ++k) scale[k] = hi[k] > lo[k] ? 32.0f / (hi[k] - lo[k]) : 0.0f;
    const auto cell = [](float c) {
        c = c > 0.0f ? c : 0.0f;
        return uint32_t(int32_t(c < 31.0f ? c : 31.0f));
    };
    std::vector<std::pair<uint32_t, size_t>> keyed(n);
    for (size_t j = 0; j < n; ++j) {
        const float* o = &r.o[3 * (begin + j)];
        const float* d = &r.d[3 * (begin + j)];
        const float m = std::max(std::max(std::fabs(d[0]), std::fabs(d[1])), std::fabs(d[2]));
        const uint32_t cells[6] = {cell((o[0] - lo[0]) * scale[0]), cell((o[1] - lo[1]) * scale[1]),
                                   cell((o[2] - lo[2]) * scale[2]), cell(d[0] * (16.0f / m) + 16.0f),
                                   cell(d[1] * (16.0f / m) + 16.0f), cell(d[2] * (16.0f / m) + 16.0f)};
        uint32_t key = 0;
        for (int bit = 4; bit >= 0; --bit)
            for (int c = 0; c < 6; ++c) key = key << 1 | ((cells[c] >> bit) & 1u);
        keyed[j] = {key, begin + j};
    }
    std::stable_sort(keyed.begin(), keyed.end(),
                     [](const auto& a, const auto& b) { return a.first < b.first; });
    // The same order on any number of threads (the box, the keys and the
    // copy are made in chunks of kOrderChunk rays).
    for (int threads : {1, 2, 3}) {
        const OrderedRays ordered(r.batch, begin, end, threads);
        for (size_t i = 0; i < n; ++i)
            ASSERT_EQ(source_of(ordered, i), keyed[i].second) << i << " threads " << threads;
        for (size_t i = 0; i < n; i += 97)
            for (int k = 0; k < 3; ++k)
                ASSERT_EQ(ordered.rays().origins[3 * i + k], r.o[3 * keyed[i].second + k]);
    }
}

TEST(OrderedRays, ScatterPutsEachHitAtItsRay) {
    RandomRays r(40000);
    const size_t begin = 1000, end = 39000;
    const OrderedRays ordered(r.batch, begin, end, 3);
    const HitBatch& h = ordered.hits();
    for (size_t i = 0; i < end - begin; ++i) {
        const float src = float(source_of(ordered, i));
        h.t[i] = src;
        h.prim[i] = int32_t(src);
        h.u[i] = src + 0.25f;
        h.v[i] = src + 0.5f;
    }
    std::vector<float> t(40000, -1.0f), u(40000, -1.0f), v(40000, -1.0f);
    std::vector<int32_t> prim(40000, -7);
    HitBatch out{t.data(), prim.data(), u.data(), v.data()};
    ordered.scatter(out);
    for (size_t i = 0; i < 40000; ++i) {
        const bool inside = i >= begin && i < end;
        EXPECT_EQ(t[i], inside ? float(i) : -1.0f) << i;
        EXPECT_EQ(prim[i], inside ? int32_t(i) : -7) << i;
        EXPECT_EQ(u[i], inside ? float(i) + 0.25f : -1.0f) << i;
        EXPECT_EQ(v[i], inside ? float(i) + 0.5f : -1.0f) << i;
    }
}

TEST(OrderedRays, ScatterPutsAnIntColumnAtItsRays) {
    // The instanced path's instance index goes back like the hits.
    RandomRays r(40000);
    const size_t begin = 500, end = 38500;
    const OrderedRays ordered(r.batch, begin, end, 2);
    ASSERT_EQ(ordered.rays().count, end - begin);
    std::vector<int32_t> column(end - begin);
    for (size_t i = 0; i < column.size(); ++i) column[i] = int32_t(3 * source_of(ordered, i) + 1);
    std::vector<int32_t> out(40000, -5);
    ordered.scatter(column.data(), out.data());
    for (size_t i = 0; i < out.size(); ++i)
        EXPECT_EQ(out[i], i >= begin && i < end ? int32_t(3 * i + 1) : -5) << i;
}

TEST(OrderedRays, WhichBatchesAreSorted) {
    RandomRays r(kOrderMinRays);
    EXPECT_TRUE(order_rays(r.batch, RayOrder::Spatial));
    EXPECT_FALSE(order_rays(r.batch, RayOrder::Given));
    r.batch.count = kOrderMinRays - 1;
    EXPECT_FALSE(order_rays(r.batch, RayOrder::Spatial));
    // Rays from one point (a camera's, a light's) are coherent in origin.
    RandomRays same(kOrderMinRays);
    for (float& x : same.o) x = 1.0f;
    EXPECT_FALSE(order_rays(same.batch, RayOrder::Spatial));
    // Rays in one direction are coherent in direction.
    RandomRays parallel(kOrderMinRays);
    for (size_t i = 0; i < parallel.d.size(); ++i) parallel.d[i] = i % 3 == 0 ? 1.0f : 0.01f;
    EXPECT_FALSE(order_rays(parallel.batch, RayOrder::Spatial));
}

// RayOrder::Auto's probe: rays spread over the whole batch with their own
// limits, in groups, stopping once the steps reach the bar.
TEST(OrderedRays, TheProbeSortsOnlyLongWalks) {
    RandomRays r(kOrderMinRays + 1000);
    std::vector<size_t> probed;  // the rays the probe traced, by their tmin
    size_t calls = 0;
    uint32_t per_ray = 0;
    const CountSteps count = [&](const RayBatch& probe) {
        ++calls;
        EXPECT_LE(probe.count, kProbeGroup);
        EXPECT_EQ(probe.tmin_stride, 1u);
        for (size_t i = 0; i < probe.count; ++i) {
            const size_t src = size_t(probe.tmin[i]);
            EXPECT_EQ(probe.tmax[i], r.tmax[src]);
            for (int k = 0; k < 3; ++k) {
                EXPECT_EQ(probe.origins[3 * i + k], r.o[3 * src + k]);
                EXPECT_EQ(probe.directions[3 * i + k], r.d[3 * src + k]);
            }
            probed.push_back(src);
        }
        return uint64_t(per_ray) * probe.count;
    };
    // One step short of the bar on every ray: the whole probe, and no sort.
    per_ray = kOrderMinSteps - 1;
    EXPECT_FALSE(order_rays(r.batch, RayOrder::Auto, count));
    ASSERT_EQ(probed.size(), kProbeRays);
    EXPECT_EQ(calls, kProbeRays / kProbeGroup);
    EXPECT_EQ(probed.front(), 0u);
    EXPECT_EQ(probed.back(), r.batch.count - 1);
    EXPECT_TRUE(std::is_sorted(probed.begin(), probed.end()));
    EXPECT_EQ(std::adjacent_find(probed.begin(), probed.end()), probed.end());
    // Under Spatial the probe is not asked.
    calls = 0;
    EXPECT_TRUE(order_rays(r.batch, RayOrder::Spatial, count));
    EXPECT_EQ(calls, 0u);
    // At the bar: sorted. Walks eight times as long stop after one group.
    per_ray = kOrderMinSteps;
    EXPECT_TRUE(order_rays(r.batch, RayOrder::Auto, count));
    calls = 0;
    per_ray = kOrderMinSteps * uint32_t(kProbeRays / kProbeGroup);
    EXPECT_TRUE(order_rays(r.batch, RayOrder::Auto, count));
    EXPECT_EQ(calls, 1u);
    // A bar of its own (an instanced scene's).
    per_ray = kOrderMinInstancedSteps - 1;
    EXPECT_FALSE(order_rays(r.batch, RayOrder::Auto, count, kOrderMinInstancedSteps));
    per_ray = kOrderMinInstancedSteps;
    EXPECT_TRUE(order_rays(r.batch, RayOrder::Auto, count, kOrderMinInstancedSteps));
    // The bars by thread count: half on one thread, in both kinds of scene.
    EXPECT_EQ(order_min_steps(false, 2), kOrderMinSteps);
    EXPECT_EQ(order_min_steps(true, 2), kOrderMinInstancedSteps);
    EXPECT_EQ(order_min_steps(false, 1), kOrderMinSteps / 2);
    EXPECT_EQ(order_min_steps(true, 1), kOrderMinInstancedSteps / 2);
    per_ray = order_min_steps(false, 1);
    EXPECT_TRUE(order_rays(r.batch, RayOrder::Auto, count, order_min_steps(false, 1)));
    EXPECT_FALSE(order_rays(r.batch, RayOrder::Auto, count, order_min_steps(false, 2)));
    // A coherent or short batch is not probed.
    calls = 0;
    r.batch.count = kOrderMinRays - 1;
    EXPECT_FALSE(order_rays(r.batch, RayOrder::Auto, count));
    EXPECT_EQ(calls, 0u);
}

}  // namespace
}  // namespace bsp
