// The watertight triangle test (triangle.hpp) on L triangles at once: the
// edge functions U, V, W of every lane, which decide hit or miss, in SIMD
// registers (GCC vector extensions: 4 lanes of SSE, 8 of AVX2, 16 of
// AVX-512). Each lane runs exactly intersect_triangle's float operations in
// its order (the build's -ffp-contract=off forbids fusing them), and a lane
// whose edge function is exactly zero is recomputed in double as there, so
// every lane's U, V, W - and so its hit, t, u and v - are bit-identical to
// the scalar test's. The distance (the plane's, in double) and u, v are only
// computed for the few lanes that pass, one by one (single_ray.hpp).
//
// The triangles are read from the scene's triangle array through the
// leaf's references, no copy in a SIMD layout: 0 extra bytes per reference
// (docs/performance.md says what the copies would cost and what was measured).
// Included by single_ray.hpp only (which checks it is compiled per
// instruction set), inside one level's namespace (see trace_kernels.cpp).
#pragma once
#include <immintrin.h>

#include <cstdint>
#include <utility>

#include "trace/triangle.hpp"

namespace bsp::BSPLAB_ISA_NS {
namespace {

// The widest block this level's registers hold: GCC's largest alignment is
// the widest vector register's size, 16 bytes on SSE2, 32 with AVX2, 64 with
// AVX-512 - 4, 8 or 16 floats.
constexpr uint32_t kWideLanes = __BIGGEST_ALIGNMENT__ / sizeof(float);
static_assert(kWideLanes == 4 || kWideLanes == 8 || kWideLanes == 16, "an x86-64 vector width");

template <uint32_t L>
struct Lanes {
    typedef float F __attribute__((vector_size(4 * L)));
    typedef int32_t I __attribute__((vector_size(4 * L)));
};

// One bit per lane whose mask is set (all ones), lane 0 in bit 0, for each
// block width. (packet.hpp has lane_bits for its own, widest, width only.)
inline uint32_t block_lane_bits(Lanes<4>::I m) {
    return uint32_t(_mm_movemask_ps(__m128(m)));
}
#if defined(__AVX2__)
inline uint32_t block_lane_bits(Lanes<8>::I m) {
    return uint32_t(_mm256_movemask_ps(__m256(m)));
}
#endif
#if defined(__AVX512F__)
inline uint32_t block_lane_bits(Lanes<16>::I m) {
    return uint32_t(_mm512_movepi32_mask(__m512i(m)));
}
#endif

// The components kx, ky, kz (the ray's shear order) of vertex `vertex` of
// the triangles of the block, one lane each. Lanes past the leaf's end
// repeat its last triangle (loads from a line already in cache, no branch);
// their lanes are masked out of the answer and of the double recompute.
template <uint32_t L, size_t... J>
inline void gather_vertex(const Triangle* tris, const uint32_t* list, uint32_t count, int vertex,
                          const int k[3], typename Lanes<L>::F out[3],
                          std::index_sequence<J...>) {
    static_assert(sizeof(Triangle) == 9 * sizeof(float), "a triangle is nine packed floats");
    const float* t[L] = {&tris[list[J < count ? J : count - 1]].v[vertex].x...};
    for (int a = 0; a < 3; ++a) out[a] = typename Lanes<L>::F{t[J][k[a]]...};
}

// The edge functions of a block of triangles and the lanes that pass.
template <uint32_t L>
struct EdgeBlock {
    typename Lanes<L>::F U, V, W;
    uint32_t passed;  // lanes whose edge functions say hit and whose det is not 0
};

// The lane's edge functions in double, as intersect_triangle does when one
// of them is exactly zero in float.
template <uint32_t L>
inline void recompute_in_double(EdgeBlock<L>& e, uint32_t lane, const typename Lanes<L>::F xy[6]) {
    const double Ax = xy[0][lane], Ay = xy[1][lane], Bx = xy[2][lane], By = xy[3][lane],
                 Cx = xy[4][lane], Cy = xy[5][lane];
    e.U[lane] = float(Cx * By - Cy * Bx);
    e.V[lane] = float(Ax * Cy - Ay * Cx);
    e.W[lane] = float(Bx * Ay - By * Ax);
}

// The edge test of the `count` (1..L) triangles list[0..count) against the
// sheared ray.
template <uint32_t L>
inline EdgeBlock<L> edge_test_block(const ShearedRay& r, const Triangle* tris,
                                    const uint32_t* list, uint32_t count) {
    using F = typename Lanes<L>::F;
    using I = typename Lanes<L>::I;
    const int k[3] = {r.kx, r.ky, r.kz};
    const float org[3] = {r.org[r.kx], r.org[r.ky], r.org[r.kz]};
    // Per vertex: its sheared 2-D position relative to the origin, exactly
    // intersect_triangle's  A = v0 - org;  Ax = A[kx] - sx * A[kz], ...
    F xy[6];
    for (int vertex = 0; vertex < 3; ++vertex) {
        F p[3];
        gather_vertex<L>(tris, list, count, vertex, k, p, std::make_index_sequence<L>());
        const F dz = p[2] - org[2];
        xy[2 * vertex] = (p[0] - org[0]) - r.sx * dz;
        xy[2 * vertex + 1] = (p[1] - org[1]) - r.sy * dz;
    }
    const F &Ax = xy[0], &Ay = xy[1], &Bx = xy[2], &By = xy[3], &Cx = xy[4], &Cy = xy[5];
    EdgeBlock<L> e;
    e.U = Cx * By - Cy * Bx;
    e.V = Ax * Cy - Ay * Cx;
    e.W = Bx * Ay - By * Ax;
    const uint32_t live = count >= 32 ? ~0u : (1u << count) - 1;
    uint32_t zero = block_lane_bits(I((e.U == 0.0f) | (e.V == 0.0f) | (e.W == 0.0f))) & live;
    for (; zero; zero &= zero - 1) recompute_in_double<L>(e, uint32_t(__builtin_ctz(zero)), xy);
    // Mixed signs miss; NaN compares false everywhere, as in the scalar test.
    const I mixed = ((e.U < 0.0f) | (e.V < 0.0f) | (e.W < 0.0f)) &
                    ((e.U > 0.0f) | (e.V > 0.0f) | (e.W > 0.0f));
    const I flat = (e.U + e.V + e.W) == 0.0f;
    e.passed = ~block_lane_bits(mixed | flat) & live;
    return e;
}

}  // namespace
}  // namespace bsp::BSPLAB_ISA_NS
