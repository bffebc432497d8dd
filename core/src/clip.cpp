#include "clip.hpp"

#include <cmath>

namespace bsp {
namespace {

// A polygon vertex with a per-axis bound on the rounding error of its
// coordinates (zero for the triangle's own vertices).
struct ClipVertex {
    Vec3 p, err;
};

constexpr int kMaxVerts = 9;  // a triangle clipped by six planes
constexpr float kRelErr = 1.0f / (1 << 21);

ClipVertex interpolate(const ClipVertex& a, const ClipVertex& b, int axis, float plane) {
    float t = (plane - a.p[axis]) / (b.p[axis] - a.p[axis]);
    ClipVertex r;
    for (int i = 0; i < 3; ++i) {
        if (i == axis) {
            r.p[i] = plane;  // on the plane by construction
            r.err[i] = 0.0f;
        } else if (a.p[i] == b.p[i]) {
            r.p[i] = a.p[i];  // no interpolation, so no rounding
            r.err[i] = std::max(a.err[i], b.err[i]);
        } else {
            r.p[i] = a.p[i] + (b.p[i] - a.p[i]) * t;
            r.err[i] = std::max(a.err[i], b.err[i]) +
                       (std::fabs(a.p[i]) + std::fabs(b.p[i])) * kRelErr;
        }
    }
    return r;
}

// Keeps the part of the polygon with sign * (p[axis] - plane) >= 0.
int clip_plane(const ClipVertex* in, int n, ClipVertex* out, int axis, float plane, float sign) {
    int m = 0;
    for (int i = 0; i < n; ++i) {
        const ClipVertex& a = in[i];
        const ClipVertex& b = in[i + 1 < n ? i + 1 : 0];
        float da = sign * (a.p[axis] - plane), db = sign * (b.p[axis] - plane);
        if (da >= 0.0f) out[m++] = a;
        if ((da < 0.0f && db > 0.0f) || (da > 0.0f && db < 0.0f))
            out[m++] = interpolate(a, b, axis, plane);
    }
    return m;
}

// Whether clip_plane would keep the polygon as it is: every vertex on the
// kept side (or on the plane), so no edge crosses it.
bool inside_plane(const ClipVertex* in, int n, int axis, float plane, float sign) {
    for (int i = 0; i < n; ++i)
        if (!(sign * (in[i].p[axis] - plane) >= 0.0f)) return false;
    return true;
}

// Clips the triangle to the box; returns the vertex count, the polygon in `out`.
int clip_to_box(const Triangle& tri, const Box& box, ClipVertex (&buf)[2][kMaxVerts + 3],
                int& cur) {
    int n = 3;
    for (int i = 0; i < 3; ++i) buf[0][i] = {tri.v[i], Vec3(0, 0, 0)};
    cur = 0;
    // Most planes of the box do not cut the triangle (the builder clips the
    // triangles a split plane straddles, which mostly lie well inside the
    // rest of the cell): those are skipped, which gives the same polygon.
    for (int axis = 0; axis < 3 && n > 0; ++axis) {
        for (float sign : {1.0f, -1.0f}) {
            const float plane = sign > 0 ? box.lo[axis] : box.hi[axis];
            if (n == 0 || inside_plane(buf[cur], n, axis, plane, sign)) continue;
            n = clip_plane(buf[cur], n, buf[1 - cur], axis, plane, sign);
            cur = 1 - cur;
        }
    }
    return n;
}

Box padded_bounds(const ClipVertex* v, int n, const Box& box) {
    Box b;
    for (int i = 0; i < n; ++i) {
        b.extend(v[i].p - v[i].err);
        b.extend(v[i].p + v[i].err);
    }
    return b.intersect(box);
}

}  // namespace

Box clipped_bounds(const Triangle& tri, const Box& box) {
    ClipVertex buf[2][kMaxVerts + 3];
    int cur;
    const int n = clip_to_box(tri, box, buf, cur);
    return padded_bounds(buf[cur], n, box);
}

void split_clipped_bounds(const Triangle& tri, const Box& box, int axis, float pos, Box& below,
                          Box& above) {
    ClipVertex buf[2][kMaxVerts + 3];
    ClipVertex half[kMaxVerts + 4];
    int cur;
    const int n = clip_to_box(tri, box, buf, cur);
    Box bbox = box, abox = box;
    bbox.hi[axis] = pos;
    abox.lo[axis] = pos;
    int m = clip_plane(buf[cur], n, half, axis, pos, -1.0f);
    below = padded_bounds(half, m, bbox);
    m = clip_plane(buf[cur], n, half, axis, pos, 1.0f);
    above = padded_bounds(half, m, abox);
}

}  // namespace bsp
