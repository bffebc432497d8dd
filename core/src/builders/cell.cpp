#include "builders/cell.hpp"

#include <algorithm>

namespace bsp {
namespace {

// Twice the area of a planar polygon with the given unit normal; `p` is
// anything indexable to a Vec3d (an array of them, or ClipBuffer).
template <class Points>
double twice_area(const Vec3d& normal, const Points& p, size_t n) {
    Vec3d s(0, 0, 0);
    for (size_t i = 1; i + 1 < n; ++i) s = s + cross(p[i] - p[0], p[i + 1] - p[0]);
    return std::fabs(dot(s, normal));
}

// A face clipped by the sweep's plane, as raw doubles: an array of Vec3d
// would be zeroed on every use (Vec3d's members have initialisers), and
// clearing its 1.5 kB was a fifth of the area evaluation's time.
class ClipBuffer {
public:
    static constexpr size_t kCapacity = 64;
    void set(size_t i, const Vec3d& v) {
        xyz_[3 * i] = v.x;
        xyz_[3 * i + 1] = v.y;
        xyz_[3 * i + 2] = v.z;
    }
    Vec3d operator[](size_t i) const { return {xyz_[3 * i], xyz_[3 * i + 1], xyz_[3 * i + 2]}; }

private:
    double xyz_[3 * kCapacity];
};

// Cell::split's working polygons, kept per thread: a build splits a cell at
// every node, and allocating and freeing these six vectors there was a good
// part of malloc's share of the build. Found once per split through this
// out-of-line call (each use of a thread_local in a shared library is a
// look-up). add_cap runs inside split and uses ring and poly only.
struct SplitScratch {
    std::vector<Vec3d> cap, cap2, below, above;
    std::vector<std::pair<double, Vec3d>> ring;
    std::vector<Vec3d> poly;
};
[[gnu::noinline]] SplitScratch& split_scratch() {
    thread_local SplitScratch scratch;
    return scratch;
}

bool is_axis_direction(const Vec3d& n) { return (n.x != 0) + (n.y != 0) + (n.z != 0) == 1; }

// A point where an edge crosses the axis plane n.x = d, put exactly on it.
// Interpolated, its coordinate along the axis is off by an ulp of a double;
// the sweep compares float candidate positions with the cell's extent, and a
// face an ulp below its plane made that plane a candidate again inside the
// cell: an empty sliver, taken for the empty bonus, over and over down to
// the depth limit. Exact, a cell cut by axis planes alone is the very box the
// kd builder keeps.
void snap_to_axis_plane(Vec3d& x, const Vec3d& n, double d) {
    if (n.x != 0) x.x = d / n.x;
    else if (n.y != 0) x.y = d / n.y;
    else x.z = d / n.z;
}

}  // namespace

Cell Cell::from_box(const Box& b) {
    Cell c;
    const Vec3d lo(b.lo), hi(b.hi);
    auto corner = [&](int i) {
        return Vec3d(i & 1 ? hi.x : lo.x, i & 2 ? hi.y : lo.y, i & 4 ? hi.z : lo.z);
    };
    // Each face as four corners in order around it.
    const int quads[6][4] = {{0, 2, 6, 4}, {1, 3, 7, 5}, {0, 1, 5, 4},
                             {2, 3, 7, 6}, {0, 1, 3, 2}, {4, 5, 7, 6}};
    const Vec3d normals[6] = {{-1, 0, 0}, {1, 0, 0}, {0, -1, 0}, {0, 1, 0}, {0, 0, -1}, {0, 0, 1}};
    for (int f = 0; f < 6; ++f) {
        Vec3d q[4];
        for (int i = 0; i < 4; ++i) q[i] = corner(quads[f][i]);
        c.add_face(normals[f], q, 4);
    }
    return c;
}

void Cell::add_face(const Vec3d& normal, const Vec3d* p, size_t n) {
    for (size_t i = 0; i < n; ++i)
        magnitude_ = std::max(magnitude_, std::fabs(p[i].x) + std::fabs(p[i].y) + std::fabs(p[i].z));
    faces_.push_back({normal, uint32_t(pts_.size()), uint32_t(n), 0.5 * twice_area(normal, p, n)});
    pts_.insert(pts_.end(), p, p + n);
}

double Cell::area() const {
    double a = 0;
    for (const Face& f : faces_) a += f.area;
    return a;
}

void Cell::extent(const Vec3d& u, double& lo, double& hi) const {
    lo = INFINITY;
    hi = -INFINITY;
    for (const Vec3d& p : pts_) {
        const double x = dot(u, p);
        lo = std::min(lo, x);
        hi = std::max(hi, x);
    }
}

// Orders the cap's points around their centre, drops near-duplicates (each
// cut edge is met by two faces) and adds the polygon as a face.
void Cell::add_cap(const Vec3d& normal, std::vector<Vec3d>& p, double eps) {
    if (p.size() < 3) return;
    Vec3d c(0, 0, 0);
    for (const Vec3d& q : p) c = c + q;
    c = c * (1.0 / double(p.size()));
    const Vec3d helper = std::fabs(normal.x) < 0.9 ? Vec3d(1, 0, 0) : Vec3d(0, 1, 0);
    Vec3d e1 = cross(normal, helper);
    e1 = e1 * (1.0 / std::sqrt(dot(e1, e1)));
    const Vec3d e2 = cross(normal, e1);
    SplitScratch& scratch = split_scratch();
    auto& ring = scratch.ring;
    auto& poly = scratch.poly;
    ring.clear();
    poly.clear();
    for (const Vec3d& q : p) ring.push_back({std::atan2(dot(q - c, e2), dot(q - c, e1)), q});
    std::sort(ring.begin(), ring.end(), [](auto& a, auto& b) { return a.first < b.first; });
    for (auto& r : ring) {
        const Vec3d d = poly.empty() ? Vec3d(1e300, 0, 0) : r.second - poly.back();
        if (dot(d, d) > eps * eps) poly.push_back(r.second);
    }
    while (poly.size() > 1) {
        const Vec3d d = poly.front() - poly.back();
        if (dot(d, d) > eps * eps) break;
        poly.pop_back();
    }
    if (poly.size() >= 3) add_face(normal, poly.data(), poly.size());
}

bool Cell::has_face_in(const Vec3d& normal, double offset, double eps) const {
    for (const Face& f : faces_) {
        if (dot(f.normal, normal) < 1.0 - 1e-12) continue;
        bool in = true;
        for (uint32_t i = 0; i < f.count && in; ++i)
            in = std::fabs(dot(normal, pts_[f.first + i]) - offset) <= eps;
        if (in) return true;
    }
    return false;
}

void Cell::split(const Vec3d& n, double d, Cell& below, Cell& above) const {
    below = Cell();
    above = Cell();
    double lo, hi;
    extent(n, lo, hi);
    const double eps = 1e-12 * std::max({std::fabs(lo), std::fabs(hi), hi - lo, 1e-30});
    const bool on_axis = is_axis_direction(n);
    // Each part has at most one face more than the cell, each face at most
    // one vertex more, and the cap one per face: sized once, no regrowth.
    for (Cell* part : {&below, &above}) {
        part->faces_.reserve(faces_.size() + 1);
        part->pts_.reserve(pts_.size() + 2 * faces_.size());
    }
    SplitScratch& scratch = split_scratch();
    auto& [cap, cap2, b, a, ring, poly] = scratch;
    cap.clear();
    for (const Face& f : faces_) {
        b.clear();
        a.clear();
        const Vec3d* p = &pts_[f.first];
        for (uint32_t i = 0; i < f.count; ++i) {
            const Vec3d& u = p[i];
            const Vec3d& v = p[(i + 1) % f.count];
            double du = dot(n, u) - d, dv = dot(n, v) - d;
            if (std::fabs(du) <= eps) du = 0;
            if (std::fabs(dv) <= eps) dv = 0;
            if (du <= 0) b.push_back(u);
            if (du >= 0) a.push_back(u);
            if (du == 0) cap.push_back(u);
            if ((du < 0 && dv > 0) || (du > 0 && dv < 0)) {
                Vec3d x = u + (v - u) * (du / (du - dv));
                if (on_axis) snap_to_axis_plane(x, n, d);
                b.push_back(x);
                a.push_back(x);
                cap.push_back(x);
            }
        }
        if (b.size() >= 3) below.add_face(f.normal, b.data(), b.size());
        if (a.size() >= 3) above.add_face(f.normal, a.data(), a.size());
    }
    const double len = std::sqrt(dot(n, n));
    const Vec3d un = n * (1.0 / len);
    const double weld = 1e-9 * std::max({hi - lo, std::fabs(lo), std::fabs(hi), 1e-30});
    cap2 = cap;
    // Cutting at the cell's own face (d at the end of its extent) leaves a
    // flat cell on one side - that face and the cap, back to back - and the
    // whole cell on the other, which already has that face: no second cap.
    if (!below.has_face_in(un, d / len, eps)) below.add_cap(un, cap, weld);
    if (!above.has_face_in(un * -1.0, -d / len, eps)) above.add_cap(un * -1.0, cap2, weld);
}

void CellProjection::project(const Cell& cell, const Vec3d& u) {
    cell_ = &cell;
    u_ = u;
    breaks_.clear();
    coef_.clear();  // eval() must not read the previous cell's table
    faces_.clear();
    faces_.reserve(cell.faces().size());
    const auto& pts = cell.points();
    proj_.resize(pts.size());
    lo_ = INFINITY;
    hi_ = -INFINITY;
    monotone_ = true;
    // One pass: the cell's points are its faces' polygons, face after face
    // (add_face), so the cell's extent and each face's come together.
    for (const Cell::Face& f : cell.faces()) {
        // A clipped face has at most two points per vertex.
        if (2 * size_t(f.count) + 2 >= ClipBuffer::kCapacity) monotone_ = false;
        FaceInfo fi;
        fi.area = f.area;
        const double c = dot(f.normal, u);
        fi.w_below = 1.0 - c;
        fi.w_above = 1.0 + c;
        fi.faces_up = c > 0;
        fi.lo = INFINITY;
        fi.hi = -INFINITY;
        for (uint32_t i = f.first; i < f.first + f.count; ++i) {
            const double x = dot(u, pts[i]);
            proj_[i] = x;
            fi.lo = std::min(fi.lo, x);
            fi.hi = std::max(fi.hi, x);
            lo_ = std::min(lo_, x);
            hi_ = std::max(hi_, x);
        }
        fi.first = f.first;
        fi.count = f.count;
        faces_.push_back(fi);
    }
    // A general plane's face lies off its plane by the rounding of the
    // interpolated vertices (about 1e-14 of the coordinates after dozens of
    // cuts), so the plane that made it could be a candidate inside the cell
    // again and cut off an empty sliver, for the empty bonus, at every level
    // down to the depth limit. A margin far below a float's resolution
    // (1.2e-7) rules that out. Axis faces are exact (split() puts them on
    // their planes) and need none: a float plane an ulp inside still cuts.
    slack_ = is_axis_direction(u) ? 0.0 : 1e-9 * cell.magnitude();
}

void CellProjection::areas_at(double t, double& below, double& above) const {
    below = above = 0;
    const auto& pts = cell_->points();
    const auto& faces = cell_->faces();
    for (size_t k = 0; k < faces_.size(); ++k) {
        const FaceInfo& f = faces_[k];
        double b;
        if (f.lo == t && f.hi == t) {
            // A face lying in the plane (the cell's bottom or top face, t at
            // an end of the cell): a split there makes a flat cell of that
            // face and the cap back to back, on the face's own side, as
            // Cell::split does. Counted below whatever its side, the top
            // face's flat cell had no area, and cutting off the triangles
            // lying in it looked free.
            b = f.faces_up ? 0.0 : f.area;
        } else if (f.hi <= t) {
            b = f.area;
        } else if (f.lo >= t) {
            b = 0;
        } else {
            // Clip the face to u.x <= t using the stored projections.
            // Each vertex's distance is computed once and carried to the
            // next edge; the closing edge (last vertex to first) comes after
            // the loop, so no index wraps inside it (the wrap was a branch,
            // mispredicted at each face's last vertex). A vertex is written
            // always and kept by the count, without a branch. The crossing
            // stays a branch: computing every edge's point to drop the
            // branch took 10 % more instructions for the 19 M mispredicts
            // it saved (bunny's first 12,000 triangles, bsp_wn+kd K = 8).
            ClipBuffer buf;
            size_t m = 0;
            const double* d = &proj_[f.first];
            const Vec3d* p = &pts[f.first];
            const uint32_t last = f.count - 1;
            double da = d[0] - t;
            uint32_t i = 0;
            for (; i < last && m + 2 < ClipBuffer::kCapacity; ++i) {
                const double db = d[i + 1] - t;
                buf.set(m, p[i]);
                m += da <= 0;
                if ((da < 0 && db > 0) || (da > 0 && db < 0))
                    buf.set(m++, p[i] + (p[i + 1] - p[i]) * (da / (da - db)));
                da = db;
            }
            if (i == last && m + 2 < ClipBuffer::kCapacity) {
                const double db = d[0] - t;
                buf.set(m, p[last]);
                m += da <= 0;
                if ((da < 0 && db > 0) || (da > 0 && db < 0))
                    buf.set(m++, p[last] + (p[0] - p[last]) * (da / (da - db)));
            }
            b = m < 3 ? 0.0 : std::min(f.area, 0.5 * twice_area(faces[k].normal, buf, m));
        }
        below += b * f.w_below;
        above += (f.area - b) * f.w_above;
    }
}

void CellProjection::tabulate() {
    breaks_ = proj_;
    std::sort(breaks_.begin(), breaks_.end());
    breaks_.erase(std::unique(breaks_.begin(), breaks_.end()), breaks_.end());
    const size_t intervals = breaks_.size() > 1 ? breaks_.size() - 1 : 0;
    // Each interval's quadratics are fitted when a candidate first falls in
    // it (fit_interval): most intervals of a small node's cell see no
    // candidate that survives the sweep's bounds, and fitting them all was
    // an eighth of a build.
    coef_.resize(6 * intervals);
    fitted_.assign(intervals, 0);
}

void CellProjection::fit_interval(size_t j) {
    // Sample inside the interval: at the cell's ends the areas jump (a
    // face lying in the plane counts on one side only), while inside
    // they are one quadratic. Fit f(s) = a + b s + c s^2 through
    // s = h/4, h/2, 3h/4.
    const double h = breaks_[j + 1] - breaks_[j];
    double f[3][2];
    for (int i = 0; i < 3; ++i) areas_at(breaks_[j] + 0.25 * (i + 1) * h, f[i][0], f[i][1]);
    for (int k = 0; k < 2; ++k) {
        const double c = 8.0 * (f[0][k] - 2.0 * f[1][k] + f[2][k]) / (h * h);
        const double b = 2.0 * (f[2][k] - f[0][k]) / h - c * h;
        coef_[6 * j + 3 * k + 0] = f[1][k] - b * 0.5 * h - c * 0.25 * h * h;
        coef_[6 * j + 3 * k + 1] = b;
        coef_[6 * j + 3 * k + 2] = c;
    }
    fitted_[j] = 1;
}

void CellProjection::eval(double t, double& below, double& above) {
    if (coef_.empty() || t <= lo_ || t >= hi_) {
        areas_at(t, below, above);
        return;
    }
    size_t j = size_t(std::upper_bound(breaks_.begin(), breaks_.end(), t) - breaks_.begin());
    j = j == 0 ? 0 : std::min(j - 1, breaks_.size() - 2);
    if (!fitted_[j]) fit_interval(j);
    const double s = t - breaks_[j];
    const double* c = &coef_[6 * j];
    below = std::max(0.0, c[0] + s * (c[1] + s * c[2]));
    above = std::max(0.0, c[3] + s * (c[4] + s * c[5]));
}

}  // namespace bsp
