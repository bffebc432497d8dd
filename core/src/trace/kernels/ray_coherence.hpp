// Whether a range of rays is coherent: neighbours in the batch run in
// nearly the same direction (camera rays in pixel or tile order), so the
// traversal's branches predict well. Included by the kernel headers only,
// inside the namespace of one instruction-set level (see single_ray.hpp).
#pragma once
#include <algorithm>
#include <cmath>
#include <cstddef>

#include "trace/traverse.hpp"

#ifndef BSPLAB_ISA_NS
#error "ray_coherence.hpp is compiled per instruction set: include it from the kernel headers"
#endif

namespace bsp::BSPLAB_ISA_NS {
namespace {

// Up to kCoherenceSamples pairs of neighbours, spread over [begin, end):
// coherent when at least half of them are less than about 8 degrees apart
// (cosine > 0.99). Camera rays are far closer than that (a 512-pixel image
// of a 60-degree view: 0.1 degree), random directions almost never are. The
// answer only picks between two loops that give the same hits; a wrong one
// costs a few percent of speed (single_ray.hpp, trace_single_rays).
constexpr size_t kCoherenceSamples = 32;

inline bool rays_are_coherent(const RayBatch& rays, size_t begin, size_t end) {
    if (end - begin < 2) return true;
    const size_t stride = std::max<size_t>(1, (end - begin - 1) / kCoherenceSamples);
    size_t close = 0, pairs = 0;
    for (size_t i = begin; i + 1 < end && pairs < kCoherenceSamples; i += stride, ++pairs) {
        const float* a = rays.directions + 3 * i;
        const float* b = a + 3;
        const float dot = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
        const float aa = a[0] * a[0] + a[1] * a[1] + a[2] * a[2];
        const float bb = b[0] * b[0] + b[1] * b[1] + b[2] * b[2];
        // cos > 0.99 without a square root: dot > 0 and dot^2 > 0.99^2 |a|^2 |b|^2.
        close += dot > 0.0f && dot * dot > 0.9801f * aa * bb;
    }
    return 2 * close >= pairs;
}

}  // namespace
}  // namespace bsp::BSPLAB_ISA_NS
