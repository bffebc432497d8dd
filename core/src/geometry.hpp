// Small vector, box and ray types shared by the builders and the traversal.
#pragma once
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

namespace bsp {

constexpr float kInf = std::numeric_limits<float>::infinity();

struct Vec3 {
    float x = 0, y = 0, z = 0;
    Vec3() = default;
    constexpr Vec3(float x_, float y_, float z_) : x(x_), y(y_), z(z_) {}
    float operator[](int i) const { return i == 0 ? x : (i == 1 ? y : z); }
    float& operator[](int i) { return i == 0 ? x : (i == 1 ? y : z); }
    Vec3 operator+(const Vec3& b) const { return {x + b.x, y + b.y, z + b.z}; }
    Vec3 operator-(const Vec3& b) const { return {x - b.x, y - b.y, z - b.z}; }
    Vec3 operator*(float s) const { return {x * s, y * s, z * s}; }
};

inline float dot(const Vec3& a, const Vec3& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline Vec3 cross(const Vec3& a, const Vec3& b) {
    return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline Vec3 vmin(const Vec3& a, const Vec3& b) {
    return {std::min(a.x, b.x), std::min(a.y, b.y), std::min(a.z, b.z)};
}
inline Vec3 vmax(const Vec3& a, const Vec3& b) {
    return {std::max(a.x, b.x), std::max(a.y, b.y), std::max(a.z, b.z)};
}

struct Box {
    Vec3 lo{kInf, kInf, kInf};
    Vec3 hi{-kInf, -kInf, -kInf};

    void extend(const Vec3& p) { lo = vmin(lo, p); hi = vmax(hi, p); }
    void extend(const Box& b) { lo = vmin(lo, b.lo); hi = vmax(hi, b.hi); }
    bool empty() const { return lo.x > hi.x || lo.y > hi.y || lo.z > hi.z; }
    Box intersect(const Box& b) const { return {vmax(lo, b.lo), vmin(hi, b.hi)}; }
    float area() const {
        if (empty()) return 0.0f;
        Vec3 d = hi - lo;
        return 2.0f * (d.x * d.y + d.y * d.z + d.z * d.x);
    }
};

// One triangle as three vertices, the layout of the (N, 3, 3) input array.
struct Triangle {
    Vec3 v[3];
    Box bounds() const {
        Box b;
        for (const Vec3& p : v) b.extend(p);
        return b;
    }
    // The (unnormalised) normal (v1 - v0) x (v2 - v0) in double precision.
    // Differences of floats are exact in double and their products nearly
    // so, so a sliver keeps its true normal where the float cross product
    // cancels to noise or to zero; zero here means truly zero area.
    void normal_double(double n[3]) const {
        const double e1x = double(v[1].x) - v[0].x, e1y = double(v[1].y) - v[0].y,
                     e1z = double(v[1].z) - v[0].z;
        const double e2x = double(v[2].x) - v[0].x, e2y = double(v[2].y) - v[0].y,
                     e2z = double(v[2].z) - v[0].z;
        n[0] = e1y * e2z - e1z * e2y;
        n[1] = e1z * e2x - e1x * e2z;
        n[2] = e1x * e2y - e1y * e2x;
    }
};

}  // namespace bsp
