#include "trace/ray_order.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <memory>
#include <numeric>
#include <utility>
#include <vector>

#include "parallel.hpp"
#include "radix_sort.hpp"

namespace bsp {

bool order_rays(const RayBatch& rays, RayOrder order, const CountSteps& count_steps,
                uint32_t min_steps) {
    if (order == RayOrder::Given || rays.count < kOrderMinRays ||
        rays_are_coherent(rays, 0, rays.count) || origins_are_coherent(rays))
        return false;
    return order == RayOrder::Spatial || !count_steps ||
           walks_pay_for_order(rays, count_steps, min_steps);
}

bool walks_pay_for_order(const RayBatch& rays, const CountSteps& count_steps,
                         uint32_t min_steps) {
    const size_t n = std::min(rays.count, kProbeRays);
    if (n == 0) return false;
    // The probe's rays, spread evenly over the batch (the first and the
    // last among them), copied with their own limits.
    std::vector<float> o(3 * n), d(3 * n), lo(n), hi(n);
    for (size_t i = 0; i < n; ++i) {
        const size_t r = n == 1 ? 0 : i * (rays.count - 1) / (n - 1);
        std::copy_n(rays.origins + 3 * r, 3, &o[3 * i]);
        std::copy_n(rays.directions + 3 * r, 3, &d[3 * i]);
        lo[i] = rays.tmin[r * rays.tmin_stride];
        hi[i] = rays.tmax[r * rays.tmax_stride];
    }
    const uint64_t bar = uint64_t(min_steps) * n;
    uint64_t steps = 0;
    for (size_t b = 0; b < n && steps < bar; b += kProbeGroup) {
        RayBatch group;
        group.origins = &o[3 * b];
        group.directions = &d[3 * b];
        group.tmin = &lo[b];
        group.tmax = &hi[b];
        group.tmin_stride = group.tmax_stride = 1;
        group.count = std::min(kProbeGroup, n - b);
        steps += count_steps(group);
    }
    return steps >= bar;
}

ProbeHits::ProbeHits(size_t n)
    : t(n), u(n), v(n), prim(n), instance(n), steps(n), general_steps(n), tests(n), culled(n),
      box_tests(n), top_steps(n), instance_visits(n) {}

uint64_t ProbeHits::sum(const std::vector<uint32_t>& counter, size_t n) {
    return std::accumulate(counter.begin(), counter.begin() + std::ptrdiff_t(n), uint64_t(0));
}

HitBatch ProbeHits::hits() {
    HitBatch h{t.data(), prim.data(), u.data(), v.data()};
    h.steps = steps.data();
    h.general_steps = general_steps.data();
    h.tests = tests.data();
    h.culled = culled.data();
    h.box_tests = box_tests.data();
    return h;
}

namespace {

// A coordinate's cell, 0 to 31, with its five bits spread to every sixth
// bit (bit i to bit 6 i): its share of the six-way Morton code. Without a
// table or a branch: the multiplication lays five copies of the cell side
// by side, 5 bits apart (they do not overlap, so nothing carries), and copy
// i holds bit i at 5 i + i = 6 i, which the mask keeps. A NaN or a value
// below 0 takes cell 0.
inline uint32_t spread_cell(float c) {
    c = c > 0.0f ? c : 0.0f;
    // Through int32_t: SSE2 converts floats to signed integers only.
    const uint32_t x = uint32_t(int32_t(c < 31.0f ? c : 31.0f));
    constexpr uint32_t kCopies = 1u | 1u << 5 | 1u << 10 | 1u << 15 | 1u << 20;
    constexpr uint32_t kEverySixth = 1u | 1u << 6 | 1u << 12 | 1u << 18 | 1u << 24;
    return (x * kCopies) & kEverySixth;
}

// Fresh memory costs a page fault per 4 KiB on first touch, which for a
// window of rays cost more than sorting it: the buffers stay with the
// calling thread from batch to batch, grown as needed (at most a window's,
// 68 bytes a ray: 17 MiB).
struct OrderScratch {
    std::unique_ptr<uint64_t[]> keyed, tmp;
    std::unique_ptr<uint32_t[]> order;
    std::unique_ptr<float[]> origins, directions, tmin, tmax, t, u, v;
    std::unique_ptr<int32_t[]> prim;
    size_t capacity = 0;

    void reserve(size_t n) {
        if (n <= capacity) return;
        keyed.reset(new uint64_t[n]);
        tmp.reset(new uint64_t[n]);
        order.reset(new uint32_t[n]);
        origins.reset(new float[3 * n]);
        directions.reset(new float[3 * n]);
        tmin.reset(new float[n]);
        tmax.reset(new float[n]);
        t.reset(new float[n]);
        u.reset(new float[n]);
        v.reset(new float[n]);
        prim.reset(new int32_t[n]);
        capacity = n;
    }
};

OrderScratch& order_scratch() {
    thread_local OrderScratch scratch;
    return scratch;
}

}  // namespace

OrderedRays::OrderedRays(const RayBatch& rays, size_t begin, size_t end, int threads)
    : begin_(begin), count_(end - begin), threads_(std::max(1, threads)) {
    static_assert(kOrderOriginBits == 5 && kOrderDirectionBits == 5, "spread_cell takes 5 bits");
    const size_t n = count_;
    const float* o = rays.origins + 3 * begin;
    const float* d = rays.directions + 3 * begin;
    // The origins' box: the cells follow the rays, not the scene. Each
    // chunk's box, then their union (min and max are exact: the same box
    // whatever the threads).
    float lo[3], scale[3];
    {
        const size_t chunks = (n + kOrderChunk - 1) / kOrderChunk;
        std::vector<std::array<float, 6>> part(chunks);
        parallel_for(n, kOrderChunk, threads_, [&](size_t b, size_t e) {
            float blo[3], bhi[3];  // in registers, stored once
            for (int k = 0; k < 3; ++k) blo[k] = bhi[k] = o[3 * b + k];
            for (size_t i = b; i < e; ++i)
                for (int k = 0; k < 3; ++k) {
                    blo[k] = std::min(blo[k], o[3 * i + k]);
                    bhi[k] = std::max(bhi[k], o[3 * i + k]);
                }
            part[b / kOrderChunk] = {blo[0], blo[1], blo[2], bhi[0], bhi[1], bhi[2]};
        });
        float hi[3];
        for (int k = 0; k < 3; ++k) lo[k] = hi[k] = o[k];
        for (const auto& box : part)
            for (int k = 0; k < 3; ++k) {
                lo[k] = std::min(lo[k], box[k]);
                hi[k] = std::max(hi[k], box[3 + k]);
            }
        for (int k = 0; k < 3; ++k) scale[k] = hi[k] > lo[k] ? 32.0f / (hi[k] - lo[k]) : 0.0f;
    }
    // Keys: the origin's cells on bits 6 i + 3..5, the direction's (over its
    // largest component, so in [-1, 1]) on bits 6 i + 0..2; the ray's index
    // below, so the sort carries it.
    OrderScratch& scratch = order_scratch();
    scratch.reserve(n);
    uint64_t* keyed = scratch.keyed.get();
    uint64_t* const tmp = scratch.tmp.get();
    uint32_t* keys = scratch.order.get();  // the order is written over them below
    parallel_for(n, kOrderChunk, threads_, [&](size_t b, size_t e) {
        // Two loops: the keys' arithmetic alone vectorizes.
        for (size_t i = b; i < e; ++i) {
            const float* oi = o + 3 * i;
            const float* di = d + 3 * i;
            const float m =
                std::max(std::max(std::fabs(di[0]), std::fabs(di[1])), std::fabs(di[2]));
            // A zero direction (refused before tracing) would give NaN: cell 0.
            const float inv = 16.0f / m;
            keys[i] = spread_cell((oi[0] - lo[0]) * scale[0]) << 5 |
                      spread_cell((oi[1] - lo[1]) * scale[1]) << 4 |
                      spread_cell((oi[2] - lo[2]) * scale[2]) << 3 |
                      spread_cell(di[0] * inv + 16.0f) << 2 |
                      spread_cell(di[1] * inv + 16.0f) << 1 | spread_cell(di[2] * inv + 16.0f);
        }
        for (size_t i = b; i < e; ++i) keyed[i] = uint64_t(keys[i]) << 32 | uint32_t(i);
    });
    // Sorted on the 30-bit key, in three passes of 10 bits (radix_sort.hpp):
    // stable, so equal keys keep the caller's order. One thread: about a
    // fifth of the ordering's time.
    keyed = radix_sort<10, 3>(keyed, tmp, n, [](uint64_t k) { return k >> 32; });
    uint32_t* order = scratch.order.get();
    order_ = order;
    float* origins = scratch.origins.get();
    float* directions = scratch.directions.get();
    float* tmins = scratch.tmin.get();
    float* tmaxs = scratch.tmax.get();
    // The rays in their order, with per-ray limits; a shared limit stays shared.
    parallel_for(n, kOrderChunk, threads_, [&](size_t b, size_t e) {
        // Ahead by this many rays: the reads jump through the caller's arrays.
        constexpr size_t kAhead = 16;
        for (size_t i = b; i < e; ++i) {
            if (i + kAhead < e) {
                const uint32_t ahead = uint32_t(keyed[i + kAhead]);
                __builtin_prefetch(o + 3 * size_t(ahead));
                __builtin_prefetch(d + 3 * size_t(ahead));
            }
            const uint32_t r = uint32_t(keyed[i]);
            order[i] = r;
            for (int k = 0; k < 3; ++k) {
                origins[3 * i + k] = o[3 * size_t(r) + k];
                directions[3 * i + k] = d[3 * size_t(r) + k];
            }
            if (rays.tmin_stride) tmins[i] = rays.tmin[rays.tmin_stride * (begin + r)];
            if (rays.tmax_stride) tmaxs[i] = rays.tmax[rays.tmax_stride * (begin + r)];
        }
    });
    rays_.origins = origins;
    rays_.directions = directions;
    rays_.count = n;
    rays_.tmin = rays.tmin_stride ? tmins : rays.tmin;
    rays_.tmin_stride = rays.tmin_stride ? 1 : 0;
    rays_.tmax = rays.tmax_stride ? tmaxs : rays.tmax;
    rays_.tmax_stride = rays.tmax_stride ? 1 : 0;
    hits_.t = scratch.t.get();
    hits_.prim = scratch.prim.get();
    hits_.u = scratch.u.get();
    hits_.v = scratch.v.get();
}

void OrderedRays::scatter(const HitBatch& out) const {
    // Every ray's own slot: the chunks write apart.
    parallel_for(count_, kOrderChunk, threads_, [&](size_t b, size_t e) {
        for (size_t i = b; i < e; ++i) {
            const size_t r = begin_ + order_[i];
            out.t[r] = hits_.t[i];
            out.prim[r] = hits_.prim[i];
            out.u[r] = hits_.u[i];
            out.v[r] = hits_.v[i];
        }
    });
}

void OrderedRays::scatter(const int32_t* ordered, int32_t* out) const {
    parallel_for(count_, kOrderChunk, threads_, [&](size_t b, size_t e) {
        for (size_t i = b; i < e; ++i) out[begin_ + order_[i]] = ordered[i];
    });
}

}  // namespace bsp
