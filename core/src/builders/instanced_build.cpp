// The top level of an instanced scene (instanced.hpp): each instance's
// matrix checked and inverted, its mesh tree's box carried to the world, and
// a binned-SAH BVH over those boxes (build_bvh, the mesh BVH's builder).
#include <algorithm>
#include <cfloat>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>

#include "builders/bvh_build.hpp"
#include "builders/memory.hpp"
#include "frame.hpp"
#include "instanced.hpp"

namespace bsp {

namespace {

// A matrix whose determinant is this small against its norm cubed maps some
// direction to (nearly) nothing: its inverse would carry rays into object
// space with errors of the order of 1 / this, so it is refused.
constexpr double kSingularDeterminant = 1e-12;
// World boxes are padded by this much of their coordinates' magnitude: the
// rounding of the corners' transform (a few ulps of double) and of the ray's
// transform back (a few of float) must never make the top level skip an
// instance the flattened scene's ray would hit.
constexpr double kBoxPadRel = 1.0 / (1 << 18);

std::string instance_name(size_t i) { return "instance " + std::to_string(i); }

// A number as printf's %g writes it: a determinant of 1e-13 reads 1e-13, not
// std::to_string's 0.000000.
std::string shortest(double x) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%g", x);
    return buf;
}

// The inverse of x = A x' + b (row-major 3 x 4), or throws.
void invert(const double* m, double* inv, size_t i) {
    for (int k = 0; k < 12; ++k)
        if (!std::isfinite(m[k]))
            throw std::invalid_argument(instance_name(i) + ": its matrix has a non-finite entry");
    const double a = m[0], b = m[1], c = m[2], d = m[4], e = m[5], f = m[6], g = m[8], h = m[9],
                 k = m[10];
    const double c00 = e * k - f * h, c01 = c * h - b * k, c02 = b * f - c * e;
    const double c10 = f * g - d * k, c11 = a * k - c * g, c12 = c * d - a * f;
    const double c20 = d * h - e * g, c21 = b * g - a * h, c22 = a * e - b * d;
    const double det = a * c00 + b * c10 + c * c20;
    double norm = 0;  // the largest row's length: |A| within sqrt(3)
    for (int r = 0; r < 3; ++r)
        norm = std::max(norm, std::sqrt(m[4 * r] * m[4 * r] + m[4 * r + 1] * m[4 * r + 1] +
                                        m[4 * r + 2] * m[4 * r + 2]));
    if (!(std::fabs(det) > kSingularDeterminant * norm * norm * norm) || !std::isfinite(det))
        throw std::invalid_argument(
            instance_name(i) + ": its matrix is singular (determinant " + shortest(det) +
            "): it flattens the mesh, and a ray cannot be carried into its object space");
    const double r = 1.0 / det;
    const double A[9] = {c00 * r, c01 * r, c02 * r, c10 * r, c11 * r, c12 * r,
                         c20 * r, c21 * r, c22 * r};
    for (int row = 0; row < 3; ++row) {
        for (int col = 0; col < 3; ++col) inv[4 * row + col] = A[3 * row + col];
        inv[4 * row + 3] = -(A[3 * row] * m[3] + A[3 * row + 1] * m[7] + A[3 * row + 2] * m[11]);
    }
}

// The world box of an object-space box under x = A x' + b, padded outwards.
// (The mesh tree's box, in its frame and scaled space, back in object space first.)
Box world_box(const Tree& tree, const double* m) {
    const Box& object = tree.bounds;
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (int corner = 0; corner < 8; ++corner) {
        const double p[3] = {
            to_world(corner & 1 ? object.hi.x : object.lo.x, 0, tree.offset, tree.scale),
            to_world(corner & 2 ? object.hi.y : object.lo.y, 1, tree.offset, tree.scale),
            to_world(corner & 4 ? object.hi.z : object.lo.z, 2, tree.offset, tree.scale)};
        for (int r = 0; r < 3; ++r) {
            const double x = m[4 * r] * p[0] + m[4 * r + 1] * p[1] + m[4 * r + 2] * p[2] + m[4 * r + 3];
            lo[r] = std::min(lo[r], x);
            hi[r] = std::max(hi[r], x);
        }
    }
    double mag = 0;
    for (int r = 0; r < 3; ++r) mag = std::max({mag, std::fabs(lo[r]), std::fabs(hi[r])});
    if (!(mag <= 0.5 * double(FLT_MAX)))  // the caller names the instance
        throw std::range_error("its matrix carries the mesh beyond float's range (a coordinate of " +
                               shortest(mag) + ")");
    const double pad = kBoxPadRel * mag + 1e-30;
    Box b;
    for (int r = 0; r < 3; ++r) {
        b.lo[r] = std::nextafter(float(lo[r] - pad), -INFINITY);
        b.hi[r] = std::nextafter(float(hi[r] + pad), INFINITY);
    }
    return b;
}

}  // namespace

TopLevel TopLevel::from_nodes(const std::vector<BvhNode>& nodes) {
    TopLevel top;
    if (nodes.empty()) return top;
    top.nodes = nodes.size();
    top.root = nodes[0].box();
    top.root_link = {nodes[0].first, nodes[0].bits};
    top.pairs.resize((nodes.size() - 1) / 2);
    for (size_t i = 0; i < nodes.size(); ++i) {
        const BvhNode& n = nodes[i];
        // build_bvh's layout, which the pair index relies on.
        if (!n.is_leaf() && (n.left() % 2 != 1 || n.right() >= nodes.size()))
            throw std::logic_error("top level: children not in pairs at 2p + 1, 2p + 2");
        if (i == 0) continue;
        Pair& p = top.pairs[(i - 1) / 2];
        const int lane = int((i - 1) % 2);
        for (int k = 0; k < 3; ++k) {
            p.axis[k][lane] = n.lo[k];
            p.axis[k][2 + lane] = n.hi[k];
        }
        p.link[lane] = {n.first, n.bits};
    }
    return top;
}

BvhNode TopLevel::node(size_t i) const {
    Box b = root;
    Link l = root_link;
    if (i > 0) {
        const Pair& p = pairs[(i - 1) / 2];
        const int lane = int((i - 1) % 2);
        for (int k = 0; k < 3; ++k) {
            b.lo[k] = p.axis[k][lane];
            b.hi[k] = p.axis[k][2 + lane];
        }
        l = p.link[lane];
    }
    BvhNode n = BvhNode::leaf(b, l.first, 0);
    n.bits = l.bits;
    return n;
}

void check_instance_matrices(const std::vector<double>& matrices) {
    if (matrices.size() % 12 != 0)
        throw std::invalid_argument("check_instance_matrices: 3 x 4 matrices, 12 numbers each");
    double inverse[12];
    for (size_t i = 0; i < matrices.size() / 12; ++i) invert(matrices.data() + 12 * i, inverse, i);
}

InstancedScene build_instanced(std::vector<const Tree*> meshes,
                               const std::vector<uint32_t>& mesh_index,
                               const std::vector<double>& matrices,
                               const TopLevelSettings& settings, Progress* progress) {
    const auto start = std::chrono::steady_clock::now();
    const size_t n = mesh_index.size();
    if (matrices.size() != 12 * n)
        throw std::invalid_argument("build_instanced: one 3 x 4 matrix per instance");
    InstancedScene scene;
    scene.meshes = std::move(meshes);
    scene.instances.resize(n);
    scene.flat_offset.resize(n);
    std::vector<Box> boxes;
    std::vector<Vec3> centroids;
    std::vector<uint32_t> ids;
    uint64_t flat = 0;
    for (size_t i = 0; i < n; ++i) {
        if (progress && i % 4096 == 0) progress->check();
        Instance& inst = scene.instances[i];
        inst.mesh = mesh_index[i];
        if (inst.mesh >= scene.meshes.size())
            throw std::invalid_argument(instance_name(i) + ": mesh index " +
                                        std::to_string(inst.mesh) + " is out of range (" +
                                        std::to_string(scene.meshes.size()) + " meshes)");
        const double* world_from_object = matrices.data() + 12 * i;
        invert(world_from_object, inst.object_from_world, i);
        const Tree& tree = *scene.meshes[inst.mesh];
        scene.flat_offset[i] = flat;
        flat += tree.triangles.size();
        if (tree.bounds.empty()) continue;  // no live triangle: nothing to hit
        try {
            boxes.push_back(world_box(tree, world_from_object));
        } catch (const std::range_error& e) {
            throw std::invalid_argument(instance_name(i) + ": " + e.what());
        }
        const Box& b = boxes.back();
        centroids.push_back(Vec3(0.5f * (b.lo.x + b.hi.x), 0.5f * (b.lo.y + b.hi.y),
                                 0.5f * (b.lo.z + b.hi.z)));
        ids.push_back(uint32_t(ids.size()));
    }
    // ids index boxes[]; map the leaves back to instance numbers.
    std::vector<uint32_t> instance_of;
    instance_of.reserve(ids.size());
    for (size_t i = 0; i < n; ++i)
        if (!scene.meshes[scene.instances[i].mesh]->bounds.empty())
            instance_of.push_back(uint32_t(i));
    if (!ids.empty()) {
        BvhSettings s;
        s.bins = settings.bins;
        s.traversal_cost = settings.traversal_cost;
        s.intersect_cost = settings.intersect_cost;
        s.leaf_size = 1;
        s.threads = settings.threads;
        MemoryBudget budget(1e12);
        BvhResult r = build_bvh(boxes, centroids, ids, s, progress, budget);
        scene.top = TopLevel::from_nodes(r.nodes);
        scene.top_order.resize(r.order.size());
        for (size_t k = 0; k < r.order.size(); ++k) scene.top_order[k] = instance_of[r.order[k]];
        scene.stats.top_depth = r.max_depth;
        scene.stats.top_leaves = r.leaves;
        scene.stats.top_sah_cost = r.sah_cost;
    }
    InstancedStats& st = scene.stats;
    st.meshes = scene.meshes.size();
    st.instances = n;
    st.top_nodes = scene.top.size();
    st.top_bytes = scene.top.bytes() +
                   scene.top_order.size() * sizeof(uint32_t) + n * sizeof(Instance) +
                   n * sizeof(uint64_t);
    st.instanced_triangles = flat;
    st.top_build_seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return scene;
}

}  // namespace bsp
