#include "builders/clip.hpp"

#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <algorithm>
#include <utility>

namespace bsp {
namespace {

// The clipped polygon is computed in double and its bounds are rounded
// outwards to float once, at the end. Every vertex coordinate is then either
// exact (a triangle's own vertex, or the clipping plane itself) or within a
// few double roundings (2^-52 relative) of the true point, 2^29 times less
// than a float ulp: the float bounds contain the true clipped triangle, and
// they are no wider than the true bounds rounded outwards.
//
// Why not a pad: an earlier version interpolated in float and widened every
// created coordinate by 2^-21 of its magnitude. Two triangles sharing an edge
// that a plane cuts then overlapped by twice that pad where they only touch,
// so a split through the shared point made one of them straddle it: the kd
// tree held up to 14 % more references than the sweep builder's (which clips
// exactly) and rays made 5-6 % more tests.
struct Point {
    double v[3];
    double operator[](int i) const { return v[i]; }
};

constexpr int kMaxVerts = 9;  // a triangle clipped by six planes

// Where the segment a-b crosses the plane p[axis] = plane. The end points are
// taken in a fixed order (by their coordinate on the axis), so that two
// polygons sharing the edge get the same point bit for bit: their bounds
// then meet exactly where the triangles touch, and a split there puts each
// on its own side.
Point interpolate(Point a, Point b, int axis, double plane) {
    if (b[axis] < a[axis]) std::swap(a, b);
    const double t = (plane - a[axis]) / (b[axis] - a[axis]);
    Point r;
    for (int i = 0; i < 3; ++i)
        r.v[i] = i == axis ? plane  // on the plane by construction
                 : a[i] == b[i] ? a[i]  // no interpolation, so no rounding
                                : a[i] + (b[i] - a[i]) * t;
    return r;
}

// Keeps the part of the polygon with sign * (p[axis] - plane) >= 0.
int clip_plane(const Point* in, int n, Point* out, int axis, double plane, double sign) {
    int m = 0;
    for (int i = 0; i < n; ++i) {
        const Point& a = in[i];
        const Point& b = in[i + 1 < n ? i + 1 : 0];
        const double da = sign * (a[axis] - plane), db = sign * (b[axis] - plane);
        if (da >= 0.0) out[m++] = a;
        if ((da < 0.0 && db > 0.0) || (da > 0.0 && db < 0.0))
            out[m++] = interpolate(a, b, axis, plane);
    }
    return m;
}

// Splits the polygon at p[axis] = plane into its parts below and above, in
// one pass: the same as clip_plane with sign -1 and with sign +1 (a vertex
// on the plane goes to both, an edge crossing it gives both its point, which
// interpolate computes the same whichever way the edge runs), without
// walking the polygon and computing its crossings twice.
void split_plane(const Point* in, int n, int axis, double plane, Point* below, int& nb,
                 Point* above, int& na) {
    nb = na = 0;
    for (int i = 0; i < n; ++i) {
        const Point& a = in[i];
        const Point& b = in[i + 1 < n ? i + 1 : 0];
        const double da = a[axis] - plane, db = b[axis] - plane;
        if (da <= 0.0) below[nb++] = a;
        if (da >= 0.0) above[na++] = a;
        if ((da < 0.0 && db > 0.0) || (da > 0.0 && db < 0.0)) {
            const Point x = interpolate(a, b, axis, plane);
            below[nb++] = x;
            above[na++] = x;
        }
    }
}

// Whether clip_plane would keep the polygon as it is: every vertex on the
// kept side (or on the plane), so no edge crosses it.
bool inside_plane(const Point* in, int n, int axis, double plane, double sign) {
    for (int i = 0; i < n; ++i)
        if (!(sign * (in[i][axis] - plane) >= 0.0)) return false;
    return true;
}

// Clips the triangle to the box; returns the vertex count, the polygon in `out`.
int clip_to_box(const Triangle& tri, const Box& box, Point (&buf)[2][kMaxVerts + 3], int& cur) {
    int n = 3;
    for (int i = 0; i < 3; ++i) buf[0][i] = {{tri.v[i].x, tri.v[i].y, tri.v[i].z}};
    cur = 0;
    // A triangle inside the box needs no plane at all (the loop below would
    // test all six and skip them): one look at its float bounds says so.
    const Box tb = tri.bounds();
    if (box.lo.x <= tb.lo.x && box.lo.y <= tb.lo.y && box.lo.z <= tb.lo.z &&
        tb.hi.x <= box.hi.x && tb.hi.y <= box.hi.y && tb.hi.z <= box.hi.z)
        return n;
    // Most planes of the box do not cut the triangle (the builder clips the
    // triangles a split plane straddles, which mostly lie well inside the
    // rest of the cell): those are skipped, which gives the same polygon.
    for (int axis = 0; axis < 3 && n > 0; ++axis) {
        for (double sign : {1.0, -1.0}) {
            const double plane = sign > 0 ? box.lo[axis] : box.hi[axis];
            if (n == 0 || inside_plane(buf[cur], n, axis, plane, sign)) continue;
            n = clip_plane(buf[cur], n, buf[1 - cur], axis, plane, sign);
            cur = 1 - cur;
        }
    }
    return n;
}

// The next float towards -inf (down) or +inf (up): std::nextafter's result,
// by a step of the bits for the finite non-zero floats nearly every call
// meets (the library call was 2 % of a kd build's instructions).
float step_float(float f, bool up) {
    uint32_t u;
    std::memcpy(&u, &f, sizeof u);
    if ((u & 0x7fffffffu) == 0 || (u & 0x7f800000u) == 0x7f800000u)
        return std::nextafter(f, up ? kInf : -kInf);  // zeros, infinities, NaN
    const bool negative = u >> 31;
    u = up != negative ? u + 1 : u - 1;  // away from zero, or towards it
    std::memcpy(&f, &u, sizeof f);
    return f;
}

// The float at or below x, and at or above it: exact coordinates stay
// exact, computed ones round away from the polygon.
float round_down(double x) {
    const float f = float(x);
    return double(f) > x ? step_float(f, false) : f;
}
float round_up(double x) {
    const float f = float(x);
    return double(f) < x ? step_float(f, true) : f;
}

// The polygon's bounds in double, rounded outwards once per face: rounding
// is monotone, so this is the box of the vertices rounded one by one (which
// took six roundings a vertex, 6 % of a kd build's instructions).
Box outward_bounds(const Point* v, int n, const Box& box) {
    constexpr double kHuge = std::numeric_limits<double>::infinity();
    double lo[3] = {kHuge, kHuge, kHuge}, hi[3] = {-kHuge, -kHuge, -kHuge};
    for (int i = 0; i < n; ++i) {
        for (int k = 0; k < 3; ++k) {
            lo[k] = std::min(lo[k], v[i][k]);
            hi[k] = std::max(hi[k], v[i][k]);
        }
    }
    Box b;
    if (n > 0) {
        b.lo = Vec3(round_down(lo[0]), round_down(lo[1]), round_down(lo[2]));
        b.hi = Vec3(round_up(hi[0]), round_up(hi[1]), round_up(hi[2]));
    }
    return b.intersect(box);
}

}  // namespace

Box clipped_bounds(const Triangle& tri, const Box& box) {
    Point buf[2][kMaxVerts + 3];
    int cur;
    const int n = clip_to_box(tri, box, buf, cur);
    return outward_bounds(buf[cur], n, box);
}

void split_clipped_bounds(const Triangle& tri, const Box& box, int axis, float pos, Box& below,
                          Box& above) {
    Point buf[2][kMaxVerts + 3];
    Point lower[kMaxVerts + 4], upper[kMaxVerts + 4];
    int cur;
    const int n = clip_to_box(tri, box, buf, cur);
    Box bbox = box, abox = box;
    bbox.hi[axis] = pos;
    abox.lo[axis] = pos;
    int nb, na;
    split_plane(buf[cur], n, axis, pos, lower, nb, upper, na);
    below = outward_bounds(lower, nb, bbox);
    above = outward_bounds(upper, na, abox);
}

}  // namespace bsp
