// Convex cells of a BSP tree and their surface areas.
//
// A cell is a convex polyhedron kept as its face polygons (double precision:
// cells are cut dozens of times and only steer the heuristic, so they are
// kept accurate and never stored in the tree).
#pragma once
#include <cmath>
#include <cstdint>
#include <vector>

#include "geometry.hpp"

namespace bsp {

struct Vec3d {
    double x = 0, y = 0, z = 0;
    Vec3d() = default;
    constexpr Vec3d(double x_, double y_, double z_) : x(x_), y(y_), z(z_) {}
    explicit Vec3d(const Vec3& v) : x(v.x), y(v.y), z(v.z) {}
    Vec3d operator+(const Vec3d& b) const { return {x + b.x, y + b.y, z + b.z}; }
    Vec3d operator-(const Vec3d& b) const { return {x - b.x, y - b.y, z - b.z}; }
    Vec3d operator*(double s) const { return {x * s, y * s, z * s}; }
};
inline double dot(const Vec3d& a, const Vec3d& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline Vec3d cross(const Vec3d& a, const Vec3d& b) {
    return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}

class Cell {
public:
    struct Face {
        Vec3d normal;  // outward, unit length
        uint32_t first, count;
        double area;
    };

    static Cell from_box(const Box& box);

    double area() const;
    bool empty() const { return faces_.empty(); }
    // The range of u.x over the cell.
    void extent(const Vec3d& u, double& lo, double& hi) const;
    // Cuts the cell by the plane n.x = d into the parts below and above it.
    void split(const Vec3d& n, double d, Cell& below, Cell& above) const;
    // The largest |x| + |y| + |z| of its points: the scale of their rounding.
    double magnitude() const { return magnitude_; }
    const std::vector<Vec3d>& points() const { return pts_; }
    const std::vector<Face>& faces() const { return faces_; }

private:
    std::vector<Vec3d> pts_;  // face polygons, concatenated
    std::vector<Face> faces_;
    double magnitude_ = 0;  // kept by add_face, the one writer of pts_
    void add_face(const Vec3d& normal, const Vec3d* p, size_t n);
    void add_cap(const Vec3d& normal, std::vector<Vec3d>& p, double eps);
    // Whether a face with this outward normal lies in the plane normal.x = offset.
    bool has_face_in(const Vec3d& normal, double offset, double eps) const;
};

// A cell seen along one direction u: what the sweep needs to price planes
// u.x = t. Surface areas below/above t come from the faces alone (the cap's
// area follows from the closed surface's zero vector area); faces wholly on
// one side cost nothing, only the faces t crosses are clipped.
class CellProjection {
public:
    CellProjection() = default;
    CellProjection(const Cell& cell, const Vec3d& u) { project(cell, u); }
    // Sees `cell` along u from now on (any earlier table is dropped). One
    // object re-projected keeps its arrays: a build projects every node's
    // cell K times, and BSP_IZE once per candidate plane.
    void project(const Cell& cell, const Vec3d& u);
    double lo() const { return lo_; }
    double hi() const { return hi_; }
    // Whether the plane u.x = t cuts the cell in two: inside its extent by
    // more than the rounding of the cell's vertices along u (slack_).
    bool cuts(double t) const { return t > lo_ + slack_ && t < hi_ - slack_; }
    // About how many distinct vertex projections there are (each vertex of a
    // simple polytope lies on three faces); tabulating costs twice that.
    size_t breaks_estimate() const { return proj_.size() / 3 + 1; }
    void areas_at(double t, double& below, double& above) const;
    // Whether the area below t, as computed, never falls as t rises beyond
    // rounding: true unless a face has so many vertices that its clip
    // could overflow areas_at's buffer and be cut short.
    bool areas_monotone() const { return monotone_; }

    // Between two consecutive vertex projections both areas are quadratic in
    // t, so three exact evaluations per interval tabulate them (ALGORITHMS.md
    // section 3). After tabulate(), eval() is one look-up per candidate
    // strictly inside the cell (at its ends it evaluates directly), and the
    // first candidate in an interval fits that interval.
    void tabulate();
    void eval(double t, double& below, double& above);

private:
    struct FaceInfo {
        double area, w_below, w_above, lo, hi;
        uint32_t first, count;
        bool faces_up;  // its outward normal points along +u
    };
    const Cell* cell_ = nullptr;
    Vec3d u_;
    double lo_ = 0, hi_ = 0;
    double slack_ = 0;
    bool monotone_ = true;
    std::vector<double> proj_;    // projection of every face point
    std::vector<FaceInfo> faces_;
    std::vector<double> breaks_;  // sorted distinct projections
    std::vector<double> coef_;    // per interval: below a,b,c then above a,b,c (s = t - break)
    std::vector<uint8_t> fitted_;  // per interval: its coef_ computed yet
    void fit_interval(size_t j);
};

}  // namespace bsp
