#include "inspect/tree_geometry.hpp"

#include "inspect/bvh_geometry.hpp"

#include <algorithm>
#include <cmath>
#include <deque>
#include <stdexcept>
#include <string>

namespace bsp {
namespace {

void check_root(const Tree& tree, uint32_t root) {
    if (root >= tree.nodes.size())
        throw std::invalid_argument("root " + std::to_string(root) + " is out of range: the tree has " +
                                    std::to_string(tree.nodes.size()) + " nodes");
}

uint32_t below_child(uint32_t index) { return index + 1; }

uint32_t above_child(const Node& n) { return n.is_kd() ? n.kd_above() : n.general_above(); }

// The split plane of an interior node in the tree's scaled space, with a
// unit normal (the cell code wants one: it compares face normals by their
// dot product with 1).
void scaled_plane(const Tree& tree, const Node& n, Vec3d& normal, double& d) {
    if (n.is_kd()) {
        normal = Vec3d(0, 0, 0);
        (n.axis() == 0 ? normal.x : n.axis() == 1 ? normal.y : normal.z) = 1.0;
        d = n.split;
        return;
    }
    const Plane& p = tree.planes[n.first];
    const Vec3d raw(p.nx, p.ny, p.nz);
    const double len = std::sqrt(dot(raw, raw));
    normal = raw * (1.0 / len);
    d = p.d / len;
}

// Whether the scaled point lies below the node's plane, with the very
// arithmetic the builders use to sort the children (below is n.x < d).
bool is_below(const Tree& tree, const Node& n, const double p[3]) {
    if (n.is_kd()) return p[n.axis()] < double(n.split);
    const Plane& q = tree.planes[n.first];
    return double(q.nx) * p[0] + double(q.ny) * p[1] + double(q.nz) * p[2] < double(q.d);
}

// The cell of node `target`: the root box cut along the path down to it.
Cell cell_of(const Tree& tree, uint32_t target) {
    Cell cell = Cell::from_box(tree.bounds), below, above;
    uint32_t index = 0;
    while (index != target) {
        const Node& n = tree.nodes[index];
        // Children follow their parent in depth-first order: the target is
        // under the above child exactly when its index is not below it.
        if (n.is_leaf()) throw std::logic_error("cell_of: node not reachable from the root");
        Vec3d normal;
        double d;
        scaled_plane(tree, n, normal, d);
        cell.split(normal, d, below, above);
        const bool go_above = target >= above_child(n);
        cell = go_above ? above : below;
        index = go_above ? above_child(n) : below_child(index);
    }
    return cell;
}

// The polygon of `cell` lying in the plane normal.x = d, with the given
// outward normal: the cap that Cell::split left on one of the two parts.
const Cell::Face* face_in_plane(const Cell& cell, const Vec3d& normal, double d) {
    double lo, hi;
    cell.extent(normal, lo, hi);
    const double eps = 1e-9 * std::max({std::fabs(lo), std::fabs(hi), hi - lo, 1e-30});
    for (const Cell::Face& f : cell.faces()) {
        if (dot(f.normal, normal) < 1.0 - 1e-9) continue;
        bool in = true;
        for (uint32_t i = 0; i < f.count && in; ++i)
            in = std::fabs(dot(normal, cell.points()[f.first + i]) - d) <= eps;
        if (in) return &f;
    }
    return nullptr;
}

// A node waiting in the level-by-level walk, with its cell.
struct Pending {
    uint32_t index;
    int32_t depth;
    Cell cell;
};

// The nodes of root's subtree level by level, each with its cell: the order
// that keeps the shallow levels whole when a limit stops the walk.
class LevelWalk {
public:
    LevelWalk(const Tree& tree, uint32_t root) : tree_(tree) {
        check_root(tree, root);
        queue_.push_back({root, 0, cell_of(tree, root)});
    }
    bool next(Pending& p) {
        if (queue_.empty()) return false;
        p = std::move(queue_.front());
        queue_.pop_front();
        return true;
    }
    // Queues both children of interior node p with the parts of its cell.
    void push_children(const Pending& p, Cell&& below, Cell&& above) {
        queue_.push_back({below_child(p.index), p.depth + 1, std::move(below)});
        queue_.push_back({above_child(tree_.nodes[p.index]), p.depth + 1, std::move(above)});
    }
    void split_and_push(const Pending& p) {
        Vec3d normal;
        double d;
        scaled_plane(tree_, tree_.nodes[p.index], normal, d);
        Cell below, above;
        p.cell.split(normal, d, below, above);
        push_children(p, std::move(below), std::move(above));
    }

private:
    const Tree& tree_;
    std::deque<Pending> queue_;
};

}  // namespace

void PolygonSoup::add(const Vec3d* p, size_t n, const Tree& tree) {
    for (size_t i = 0; i < n; ++i) {
        vertices.push_back(float(to_world(p[i].x, 0, tree.offset, tree.scale)));
        vertices.push_back(float(to_world(p[i].y, 1, tree.offset, tree.scale)));
        vertices.push_back(float(to_world(p[i].z, 2, tree.offset, tree.scale)));
    }
    offsets.push_back(uint32_t(vertices.size() / 3));
}

bool world_plane(const Tree& tree, uint32_t index, double plane[4]) {
    if (tree.structure == Structure::Bvh) return false;  // boxes, no planes
    const Node& n = tree.nodes[index];
    if (n.is_leaf()) return false;
    if (n.is_kd()) {
        plane[0] = plane[1] = plane[2] = 0.0;
        plane[n.axis()] = 1.0;
        plane[3] = to_world(n.split, n.axis(), tree.offset, tree.scale);
        return true;
    }
    const Plane& p = tree.planes[n.first];
    plane[0] = p.nx;
    plane[1] = p.ny;
    plane[2] = p.nz;
    // n.(x - offset) s = d in the tree's space.
    plane[3] = double(p.d) / tree.scale + p.nx * tree.offset[0] + p.ny * tree.offset[1] +
               p.nz * tree.offset[2];
    return true;
}

namespace {

void refuse_bvh(const Tree& tree) {
    if (tree.structure == Structure::Bvh)
        throw std::invalid_argument("a BVH has no split planes: use node_boxes");
}

}  // namespace

SplitPolygons split_polygons(const Tree& tree, int max_depth, uint32_t root, size_t max_polygons) {
    refuse_bvh(tree);
    if (max_depth < 0)
        throw std::invalid_argument("max_depth must be >= 0, got " + std::to_string(max_depth));
    SplitPolygons out;
    LevelWalk walk(tree, root);
    Pending p;
    while (walk.next(p)) {
        const Node& n = tree.nodes[p.index];
        if (n.is_leaf()) continue;
        if (out.node.size() == max_polygons) {
            out.cut = true;
            break;
        }
        Vec3d normal;
        double d;
        scaled_plane(tree, n, normal, d);
        Cell below, above;
        p.cell.split(normal, d, below, above);
        // The cap is the outward face of the part below; when the plane
        // only touches the cell's lowest side, that part is empty and the
        // face is the part above's, facing the other way.
        const Cell::Face* f = face_in_plane(below, normal, d);
        const Cell& owner = f ? below : above;
        if (!f) f = face_in_plane(above, normal * -1.0, -d);
        if (f) {
            out.polygons.add(&owner.points()[f->first], f->count, tree);
            out.node.push_back(p.index);
            out.depth.push_back(p.depth);
            out.kind.push_back(uint8_t(n.kind()));
            double plane[4];
            world_plane(tree, p.index, plane);
            out.planes.insert(out.planes.end(), plane, plane + 4);
        }
        if (p.depth < max_depth) walk.push_children(p, std::move(below), std::move(above));
    }
    return out;
}

NodeCells node_cells(const Tree& tree, int max_depth, uint32_t root, size_t max_cells) {
    refuse_bvh(tree);
    NodeCells out;
    LevelWalk walk(tree, root);
    Pending p;
    while (walk.next(p)) {
        const Node& n = tree.nodes[p.index];
        if (!n.is_leaf() && p.depth != max_depth) {
            walk.split_and_push(p);
            continue;
        }
        if (out.node.size() == max_cells) {
            out.cut = true;
            break;
        }
        for (const Cell::Face& f : p.cell.faces())
            out.faces.add(&p.cell.points()[f.first], f.count, tree);
        out.cell_offsets.push_back(uint32_t(out.faces.size()));
        out.node.push_back(p.index);
        out.depth.push_back(p.depth);
        out.kind.push_back(uint8_t(n.kind()));
    }
    return out;
}

NodeAt node_at(const Tree& tree, const double p[3], int max_depth) {
    if (tree.structure == Structure::Bvh) return bvh_node_at(tree, p, max_depth);
    const double s[3] = {(p[0] - tree.offset[0]) * tree.scale, (p[1] - tree.offset[1]) * tree.scale,
                         (p[2] - tree.offset[2]) * tree.scale};
    const Box& b = tree.bounds;
    for (int k = 0; k < 3; ++k)
        if (!(s[k] >= b.lo[k] && s[k] <= b.hi[k])) return {-1, -1};
    uint32_t index = 0;
    int32_t depth = 0;
    while (!tree.nodes[index].is_leaf() && depth != max_depth) {
        const Node& n = tree.nodes[index];
        index = is_below(tree, n, s) ? below_child(index) : above_child(n);
        ++depth;
    }
    return {int64_t(index), depth};
}

}  // namespace bsp
