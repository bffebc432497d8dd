// Watertight ray-triangle intersection (Woop, Benthin & Wald, JCGT 2013).
//
// The ray is sheared so that it runs along +z from the origin; the triangle's
// edge functions are then evaluated in 2-D. Edges shared by two triangles give
// bit-identical edge functions of opposite sign, so no ray slips through a
// shared edge - the property the Embree comparison depends on.
#pragma once
#include <cmath>

#include "geometry.hpp"
#include "trace/kernel_inlining.hpp"

namespace bsp {

// Per-ray constants of the shear transform, computed once per ray. The ray
// may be tested from a point on it (the traversal's walk origin inside the
// scene box, kernels/walk_start.hpp): `t_offset` is that point's t, added
// back to the distances, so that a ray from far away is tested with the
// precision of a point near the triangles, not of |o|.
struct ShearedRay {
    Vec3 org, dir;
    int kx, ky, kz;
    float sx, sy, sz;
    double t_offset = 0.0;

    explicit ShearedRay(const Vec3& o, const Vec3& d, double t_off = 0.0)
        : org(o), dir(d), t_offset(t_off) {
        float ax = std::fabs(d.x), ay = std::fabs(d.y), az = std::fabs(d.z);
        kz = (ax > ay) ? (ax > az ? 0 : 2) : (ay > az ? 1 : 2);
        kx = kz == 2 ? 0 : kz + 1;
        ky = kx == 2 ? 0 : kx + 1;
        // Swap kx and ky to keep the winding when the dominant direction is negative.
        if (d[kz] < 0.0f) std::swap(kx, ky);
        sx = d[kx] / d[kz];
        sy = d[ky] / d[kz];
        sz = 1.0f / d[kz];
    }
};

// The ray parameter at which o + t d meets the triangle's plane, in double.
inline double plane_distance(const Triangle& tri, const Vec3& o, const Vec3& d) {
    double n[3];
    tri.normal_double(n);
    const double num = n[0] * (double(tri.v[0].x) - o.x) + n[1] * (double(tri.v[0].y) - o.y) +
                       n[2] * (double(tri.v[0].z) - o.z);
    return num / (n[0] * d.x + n[1] * d.y + n[2] * d.z);
}

// The ray's t at the triangle's plane: from its test origin, plus t_offset.
inline double ray_distance(const Triangle& tri, const ShearedRay& r) {
    return r.t_offset + plane_distance(tri, r.org, r.dir);
}

struct TriangleHit {
    float t, u, v;
    double td;  // t before its rounding to float (ray_distance)
};

// The component k of v, read from memory rather than chosen by
// Vec3::operator[]'s branches: the shear's axes kx, ky, kz change from ray
// to ray, and on incoherent rays those branches mispredicted about twice a
// ray (callgrind, bunny, random rays). The same float, so the same test.
inline float component(const Vec3& v, int k) {
    const float c[3] = {v.x, v.y, v.z};
    return c[k];
}

// A hit's u, v from its edge functions: V / det and W / det with det =
// U + V + W, through the float reciprocal. Where that overflows (|det| below
// 1 / FLT_MAX: a ray all but lying in the triangle's plane, whose sheared
// edge functions are all tiny) the products would be 0 * inf and x * inf,
// NaN and inf; there the quotients are taken in double, which keeps them in
// [0, 1]. Every kernel takes its u, v from here (or, in packets, the same
// operations lane by lane), so they stay the same bit for bit on every path.
BSPLAB_KERNEL_SHARED_INLINE void barycentrics(float U, float V, float W, float& u, float& v) {
    const float det = U + V + W;
    const float inv = 1.0f / det;
    if (std::isinf(inv)) [[unlikely]] {
        u = float(double(V) / double(det));
        v = float(double(W) / double(det));
        return;
    }
    u = V * inv;
    v = W * inv;
}

// Returns true and fills `hit` when the ray hits the triangle with
// tmin < t < tmax, or t == tmax with a double distance below `tie_td`, or
// equal to it when `tie_wins` (the traversal's tie rule, single_ray.hpp's
// Closest: of equally close float hits the nearer in double wins, then the
// smallest triangle index).
// u, v follow Embree: p = (1-u-v) v0 + u v1 + v v2.
BSPLAB_KERNEL_SHARED_INLINE bool intersect_triangle(const ShearedRay& r, const Triangle& tri,
                                                    float tmin, float tmax, TriangleHit& hit,
                                                    double tie_td = -INFINITY,
                                                    bool tie_wins = false) {
    const Vec3 A = tri.v[0] - r.org, B = tri.v[1] - r.org, C = tri.v[2] - r.org;
    const float Az = component(A, r.kz), Bz = component(B, r.kz), Cz = component(C, r.kz);
    const float Ax = component(A, r.kx) - r.sx * Az, Ay = component(A, r.ky) - r.sy * Az;
    const float Bx = component(B, r.kx) - r.sx * Bz, By = component(B, r.ky) - r.sy * Bz;
    const float Cx = component(C, r.kx) - r.sx * Cz, Cy = component(C, r.ky) - r.sy * Cz;
    float U = Cx * By - Cy * Bx;
    float V = Ax * Cy - Ay * Cx;
    float W = Bx * Ay - By * Ax;
    // On an edge the single-precision edge function can round to zero;
    // recompute those in double so that the edge is decided consistently.
    // (Bitwise | and &, not || and &&: one branch each where short-circuit
    // evaluation took up to three, which mispredicted about once a test on
    // incoherent rays - callgrind, sportscar, random rays, the BVH.)
    if ((U == 0.0f) | (V == 0.0f) | (W == 0.0f)) {
        U = float(double(Cx) * double(By) - double(Cy) * double(Bx));
        V = float(double(Ax) * double(Cy) - double(Ay) * double(Cx));
        W = float(double(Bx) * double(Ay) - double(By) * double(Ax));
    }
    const bool negative = (U < 0.0f) | (V < 0.0f) | (W < 0.0f);
    const bool positive = (U > 0.0f) | (V > 0.0f) | (W > 0.0f);
    if (negative & positive) return false;
    const float det = U + V + W;
    if (det == 0.0f) return false;
    // The edge functions decide hit or miss (watertight). The distance comes
    // from the triangle's plane instead of the sheared depths: with large
    // coordinates and a nearby plane the sheared sum cancels badly, while
    // N.(v0 - o) / N.d stays accurate. In double precision, because a
    // sliver's float normal is off by the cancellation of two nearly
    // parallel edges (a 3 x 0.009 triangle gave t off by 7e-4 in float);
    // differences of floats are exact in double, so this costs a few
    // multiplications per hit, not per test.
    const double t = ray_distance(tri, r);
    const float tf = float(t);
    if (!(tf > tmin && (tf < tmax || (tf == tmax && (t < tie_td || (tie_wins && t == tie_td))))))
        return false;
    hit.t = tf;
    hit.td = t;
    barycentrics(U, V, W, hit.u, hit.v);
    return true;
}

}  // namespace bsp
