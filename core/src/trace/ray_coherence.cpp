#include "trace/ray_coherence.hpp"

#include <algorithm>

namespace bsp {

bool rays_are_coherent(const RayBatch& rays, size_t begin, size_t end) {
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

bool origins_are_coherent(const RayBatch& rays) {
    const size_t n = rays.count;
    if (n < 4) return true;
    const size_t half = n / 2;
    const size_t stride = std::max<size_t>(1, (half - 1) / kCoherenceSamples);
    const auto distance2 = [&](size_t a, size_t b) {
        const float* p = rays.origins + 3 * a;
        const float* q = rays.origins + 3 * b;
        const float x = p[0] - q[0], y = p[1] - q[1], z = p[2] - q[2];
        return x * x + y * y + z * z;
    };
    constexpr float kShare2 = kOrderedOriginShare * kOrderedOriginShare;
    size_t near = 0, samples = 0;
    for (size_t i = 0; i + 1 < half && samples < kCoherenceSamples; i += stride, ++samples)
        near += distance2(i, i + 1) <= kShare2 * distance2(i, i + half);
    return 2 * near >= samples;
}

}  // namespace bsp
