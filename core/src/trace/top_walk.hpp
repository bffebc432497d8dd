// The walk of an instanced scene's top level (instanced.hpp), once: the box
// test (TopRay), the ray carried into an instance's object space
// (object_ray), the closest hit over instances (Closest) and one ray's walk
// (walk_top), nearest box first, two levels a step. The single-ray trace
// (instanced_traverse.cpp) runs walk_top counting; the recorded walk
// (instanced_trace_path.cpp) runs the same walk recording each node and
// instance it visits, so its hit and counts are intersect_instanced()'s by
// construction. The packet path walks groups of rays with the same pieces.
//
// A header of the trace files, not of the API: everything here is inline,
// for the walk's loop to be compiled into each caller with its policy.
#pragma once
#include <algorithm>
#include <cfloat>
#include <cmath>
#include <cstdint>
#include <limits>
#include <type_traits>

#include <emmintrin.h>
#include <xmmintrin.h>

#include "instanced.hpp"

namespace bsp::top_walk {

// The top level's stack: one entry per level (kBvhMaxDepth bounds the depth).
constexpr int kTopStack = 64 + 1;  // + 1: the walk writes one slot past the top (mask != 3)

// The top level's box test, both children of a node at once in SSE: per
// axis the lanes (A near, B near, A far, B far) - the near face the high one
// where d < 0, loaded as such from the pair's axis (TopLevel::Pair) - their
// crossings (x - o) / d in float, the far lanes negated,
// so that one MAXPS per axis gives both entries and both (negated) exits.
// Float is conservative here with a per-ray bound: a crossing's rounding is
// at most three of 2^-24 of |x - o| |1/d| <= (the scene's largest coordinate
// + |o|) |1/d|, and every crossing is widened by 2^-21 of that (kCrossSlack),
// so a box's range holds the exact ray's range in it; the boxes are padded
// besides (instanced_build.cpp). A NaN crossing (an origin in a face plane,
// the ray parallel to it) loses the max and is ignored.
constexpr float kCrossSlack = 1.0f / (1 << 21);

struct TopRay {
    __m128 org[3], sidir[3], err[3];
    float o[3], inv[3], e[3];
    bool neg[3];
    int near_off[3], far_off[3];  // in a TopLevel::Pair axis: the near faces' lanes, the far faces'

    TopRay() = default;
    TopRay(const float* of, const float* df, float scene_max) {
        for (int k = 0; k < 3; ++k) {
            o[k] = of[k];
            inv[k] = 1.0f / df[k];
            e[k] = df[k] == 0.0f ? 0.0f : kCrossSlack * (scene_max + std::fabs(of[k])) * std::fabs(inv[k]);
            neg[k] = std::signbit(df[k]);
            near_off[k] = neg[k] ? 2 : 0;
            far_off[k] = neg[k] ? 0 : 2;
            org[k] = _mm_set1_ps(o[k]);
            sidir[k] = _mm_setr_ps(inv[k], inv[k], -inv[k], -inv[k]);
            err[k] = _mm_set1_ps(e[k]);
        }
    }

    // Which of the children A, B the ray enters within [s0, s1] (bit 0: A,
    // bit 1: B) and their entries. The lanes' arithmetic as above; the
    // entered test "entry <= exit" on the negated exits' sign flipped back
    // (exact), in SSE, so that the walk branches once on the mask and not
    // on two floats read back from memory.
    int pair(const TopLevel::Pair& p, float s0, float s1, float& a0, float& b0) const {
        const __m128 acc = crossings(p, s0, s1);
        const __m128 exits = _mm_xor_ps(_mm_movehl_ps(acc, acc), _mm_set1_ps(-0.0f));
        a0 = _mm_cvtss_f32(acc);
        b0 = _mm_cvtss_f32(_mm_shuffle_ps(acc, acc, _MM_SHUFFLE(1, 1, 1, 1)));
        return _mm_movemask_ps(_mm_cmple_ps(acc, exits)) & 3;
    }

    // The same test's exits (out[0]: A's, out[1]: B's), for the recorded
    // walk: the same arithmetic, so the same floats.
    void pair_exits(const TopLevel::Pair& p, float s0, float s1, float out[2]) const {
        const __m128 acc = crossings(p, s0, s1);
        const __m128 exits = _mm_xor_ps(_mm_movehl_ps(acc, acc), _mm_set1_ps(-0.0f));
        out[0] = _mm_cvtss_f32(exits);
        out[1] = _mm_cvtss_f32(_mm_shuffle_ps(exits, exits, _MM_SHUFFLE(1, 1, 1, 1)));
    }

    // Per lane the latest entry (A, B) and the earliest exit negated (A, B)
    // of the pair's boxes within [s0, s1].
    __m128 crossings(const TopLevel::Pair& p, float s0, float s1) const {
        __m128 acc = _mm_setr_ps(s0, s0, -s1, -s1);
        for (int k = 0; k < 3; ++k) {
            // (A near, B near, A far, B far): two 8-byte loads.
            const float* f = p.axis[k];
            const __m128 nearv = _mm_castpd_ps(_mm_load_sd(reinterpret_cast<const double*>(f + near_off[k])));
            const __m128 c = _mm_loadh_pi(nearv, reinterpret_cast<const __m64*>(f + far_off[k]));
            const __m128 t = _mm_sub_ps(_mm_mul_ps(_mm_sub_ps(c, org[k]), sidir[k]), err[k]);
            acc = _mm_max_ps(t, acc);
        }
        return acc;
    }

    // One box (the root): the same arithmetic, lane by lane.
    bool clip(const Box& b, float& t0, float& t1) const {
        for (int k = 0; k < 3; ++k) {
            const float nearf = neg[k] ? b.hi[k] : b.lo[k], farf = neg[k] ? b.lo[k] : b.hi[k];
            const float tn = (nearf - o[k]) * inv[k] - e[k];
            const float tf = (farf - o[k]) * -inv[k] - e[k];
            if (tn > t0) t0 = tn;
            if (tf > -t1) t1 = -tf;
        }
        return t0 <= t1;
    }
};

// The ray in the instance's object space, rounded once to float: false when
// no float ray is there - beyond float's range (a ray from 10^38 units away
// to a small mesh) or a direction that underflows to zero.
// Out of line, as the compiler chose it when this was private to
// instanced_traverse.cpp: inlined into the walks it cost the packet path 2 %
// more instructions a ray (callgrind, city kd, random rays).
__attribute__((noinline)) inline bool object_ray(const Instance& inst, const double o[3], const double d[3], float ob[3],
                       float db[3]) {
    const double* m = inst.object_from_world;
    bool representable = true;
    for (int r = 0; r < 3; ++r) {
        const double x = m[4 * r] * o[0] + m[4 * r + 1] * o[1] + m[4 * r + 2] * o[2] + m[4 * r + 3];
        const double y = m[4 * r] * d[0] + m[4 * r + 1] * d[1] + m[4 * r + 2] * d[2];
        representable &= std::fabs(x) <= double(FLT_MAX) && std::fabs(y) <= double(FLT_MAX);
        ob[r] = representable ? float(x) : 0.0f;
        db[r] = representable ? float(y) : 0.0f;
    }
    return representable && (db[0] != 0.0f || db[1] != 0.0f || db[2] != 0.0f);
}

// A ray's closest hit over the instances so far.
struct Closest {
    float t = kInf, u = 0, v = 0;
    int32_t prim = -1, instance = -1;
    uint64_t flat = std::numeric_limits<uint64_t>::max();

    // The segment's end for the next instance: one ulp beyond the closest
    // hit, so that a hit at the same t comes back and the tie rule can take it.
    float limit(float tmax) const { return prim < 0 ? tmax : std::nextafter(t, kInf); }
    // The nearer hit, and of equal t the smaller flattened index (the
    // flattened scene's tie rule between instances).
    void take(float ht, float hu, float hv, int32_t hprim, uint32_t id, uint64_t hflat) {
        if (ht < t || (ht == t && hflat < flat)) {
            t = ht;
            u = hu;
            v = hv;
            prim = hprim;
            instance = int32_t(id);
            flat = hflat;
        }
    }
    void write(const HitBatch& hits, const InstanceHits& extra, size_t i) const {
        hits.t[i] = prim >= 0 ? t : kInf;
        hits.prim[i] = prim;
        hits.u[i] = u;
        hits.v[i] = v;
        extra.instance[i] = instance;
    }
};

// The scene's largest coordinate: the top level's crossing bound (TopRay).
inline float scene_max_of(const InstancedScene& scene) {
    float m = 0.0f;
    if (!scene.top.empty())
        for (int k = 0; k < 3; ++k)
            m = std::max({m, std::fabs(scene.top.root.lo[k]), std::fabs(scene.top.root.hi[k])});
    return m;
}

// A top-level node visited: its number (TopLevel::node's) and the ray's
// range in its box, as the test that entered it found them. Kept only by a
// recording policy; a counting one gets zeros.
struct TopVisit {
    uint32_t node = 0;
    float t0 = 0, t1 = 0;
};

// What a mesh tree's trace of the ray in an instance's object space found.
struct BottomHit {
    float t = kInf, u = 0, v = 0;
    int32_t prim = -1;
};

// One ray's walk through the top level, the closest hit over the instances
// it enters in `best` (best.t starting at tmax). The policy:
//   static constexpr bool kRecords;  // visits carry their node and range
//   void top_step(const TopVisit&);  // each top-level node visited
//   void trace_instance(uint32_t id, const Instance&, const float ob[3],
//               const float db[3], float tmin, float limit, BottomHit&);
//                                    // trace instance id's mesh tree
// o, d are the ray's origin and direction (of, df) in double.
template <class Policy>
inline void walk_top(const InstancedScene& scene, const TopRay& ray, const double o[3],
                     const double d[3], float tmin, float tmax, Closest& best, Policy& policy) {
    constexpr bool kRecords = Policy::kRecords;
    struct Empty {};
    using Visit = std::conditional_t<kRecords, TopVisit, Empty>;
    const TopLevel::Pair* pairs = scene.top.pairs.data();
    struct Entry {
        TopLevel::Link node;
        float t0;
        [[no_unique_address]] Visit visit;
    } stack[kTopStack];
    int top = 0;
    float t0 = tmin, t1 = tmax;
    // The walk visits the nearer entered child at once and pushes the
    // farther: the order of popping the nearer off the stack, without the
    // store and the reload, and with one branch on the pair's mask where two
    // on its floats mispredicted about eight times a ray (callgrind, city).
    // A child's link comes with its pair's boxes (TopLevel::Pair).
    TopLevel::Link n = scene.top.root_link;
    TopVisit current;  // n's (recording only)
    // Both entered: the nearer (A on a tie) next, the other pushed; one
    // entered: that one next. In integer arithmetic, not branches: which
    // child is nearer is a coin toss to the predictor. `left`: A's node
    // number (B's is the next), `exits`: their exits (recording only).
    const auto descend = [&](const TopLevel::Pair& p, uint32_t left, int mask, float a0,
                             float b0, const float* exits) {
        const unsigned a_in = unsigned(mask) & 1u, b_in = unsigned(mask) >> 1;
        const unsigned near_b = b_in & ((a_in ^ 1u) | unsigned(b0 < a0));
        const float entry[2] = {a0, b0};  // indexed: no branch
        stack[top].node = p.link[near_b ^ 1u];
        stack[top].t0 = entry[near_b ^ 1u];
        if constexpr (kRecords) {
            stack[top].visit = {left + (near_b ^ 1u), entry[near_b ^ 1u], exits[near_b ^ 1u]};
            current = {left + near_b, entry[near_b], exits[near_b]};
        }
        top += int(a_in & b_in);
        return near_b;
    };
    bool live = !scene.top.empty() && ray.clip(scene.top.root, t0, t1);
    if constexpr (kRecords) current = {0, t0, t1};
    while (live) {
        policy.top_step(current);
        if (!n.is_leaf()) {
            // Two levels a step: the node's pair and both children's pairs
            // tested at once (a leaf child stands in pair 0, its result
            // unused), so the child's test does not wait on the node's. One
            // test a level, the walk was bound by the chain load -> test ->
            // choice -> load, not by its instructions: 8 % fewer of them (the
            // pair layout) left city bvh's primary rays at 422 ns; tested
            // ahead they take 365 ns with 10 % more instructions (callgrind
            // 2,896 -> 3,172 a ray). The visits, their order and every
            // test's result are the same: no leaf comes between a node and
            // its child, so best.t is too.
            const uint32_t left = n.left();
            const TopLevel::Pair& p = TopLevel::pair_of(pairs, left);
            const uint32_t child_left[2] = {p.link[0].is_leaf() ? 1u : p.link[0].left(),
                                            p.link[1].is_leaf() ? 1u : p.link[1].left()};
            const TopLevel::Pair* child[2] = {&TopLevel::pair_of(pairs, child_left[0]),
                                              &TopLevel::pair_of(pairs, child_left[1])};
            float a0, b0, ca0[2], cb0[2], exits[2], cexits[2][2];
            const int mask = ray.pair(p, tmin, best.t, a0, b0);
            const int cmask[2] = {ray.pair(*child[0], tmin, best.t, ca0[0], cb0[0]),
                                  ray.pair(*child[1], tmin, best.t, ca0[1], cb0[1])};
            if constexpr (kRecords) {
                ray.pair_exits(p, tmin, best.t, exits);
                ray.pair_exits(*child[0], tmin, best.t, cexits[0]);
                ray.pair_exits(*child[1], tmin, best.t, cexits[1]);
            }
            if (mask != 0) {
                const unsigned c = descend(p, left, mask, a0, b0, exits);
                n = p.link[c];
                if (n.is_leaf()) continue;
                policy.top_step(current);  // the child, already tested
                if (cmask[c] != 0) {
                    n = child[c]->link[descend(*child[c], child_left[c], cmask[c], ca0[c],
                                               cb0[c], cexits[c])];
                    continue;
                }
            }
        } else {
            for (uint32_t k = 0; k < n.count(); ++k) {
                const uint32_t id = scene.top_order[n.first + k];
                const Instance& inst = scene.instances[id];
                float ob[3], db[3];
                if (!object_ray(inst, o, d, ob, db)) continue;
                BottomHit h;
                policy.trace_instance(id, inst, ob, db, tmin, best.limit(tmax), h);
                if (h.prim >= 0)
                    best.take(h.t, h.u, h.v, h.prim, id, scene.flat_offset[id] + uint64_t(h.prim));
            }
        }
        // The next pushed box entered before the closest hit (equal t stays:
        // the tie rule decides between instances).
        live = false;
        while (top > 0) {
            const Entry e = stack[--top];
            if (e.t0 > best.t) continue;
            n = e.node;
            if constexpr (kRecords) current = e.visit;
            live = true;
            break;
        }
    }
}

}  // namespace bsp::top_walk
