// Each node keeps, for every triangle reference, the triangle clipped to the
// node's cell (a convex polygon; the whole triangle until a plane cuts it),
// so extents along any direction are exact and a triangle is split only by
// the planes that actually cross it. Cells are convex polyhedra (cell.hpp);
// their areas below and above a moving plane are tabulated per direction.
#include "builders/bsp_build.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <future>
#include <memory>

#include "builders/build_tree.hpp"
#include "builders/cell.hpp"
#include "builders/cost_model.hpp"
#include "builders/projection_sort.hpp"
#include "builders/strategies/directions.hpp"
#include "builders/strategies/strategy.hpp"
#include "builders/sweep_bins.hpp"
#include "parallel.hpp"

namespace bsp {
namespace {

// A reference: triangle `tri`, clipped to the cell as pool[first, first+count)
// or, with count == 0, not clipped at all.
struct Ref {
    uint32_t tri, first, count;
};

struct NodeRefs {
    std::vector<Ref> refs;
    std::vector<Vec3> pool;
    Charge charge;  // both arrays' bytes in the memory budget
};

// The one projection every decision uses: sweep counts and classification
// must see bit-identical values. For an axis it is the coordinate itself.
inline float proj(const Vec3& u, const Vec3& p) { return u.x * p.x + u.y * p.y + u.z * p.z; }

struct Candidate {
    Vec3 dir;
    float pos = 0;
    bool planar_left = false;
    bool kd = false;  // stored as a kd node
    float cost = kInf;
    uint32_t n_left = 0, n_right = 0;
};

struct SweepResult {
    Candidate best;      // under the cost model's step()
    Candidate fallback;  // ^Kd: general splits at its fallback_step()
};

// Nodes with more triangles than this sweep their directions in parallel.
constexpr size_t kParallelDirections = 8192;

// A binned node (BuildQuality::Fast) counts its references into per-thread
// bins in chunks of this many references when it has more than
// kParallelDirections of them: the counts are integers, so the sum is the
// same whatever thread counted which chunk.
constexpr size_t kBinChunk = 16384;

// The depth of the stack walking BSP_IZE's per-node BVH: a subtree that
// would overflow it is counted reference by reference instead.
constexpr int kRefBvhStack = 128;

// BSP_IZE's per-node BVH over the references: a box, a centre, an order slot
// and about half a BVH node per reference.
constexpr uint64_t kIzeBytesPerRef = 2 * sizeof(Box) + sizeof(Vec3) + sizeof(uint32_t);

class BspBuilder : BuilderBase {
public:
    BspBuilder(const std::vector<Triangle>& tris, const BuildOptions& opt, Progress* progress,
               int threads, MemoryBudget& memory, NodeArena& arena)
        : BuilderBase(tris, opt, progress, threads, memory, arena) {
        // A general plane's crossing is computed as (d - n.o) / (n.dir) in
        // float, off by a few ulps of the coordinates; two planes with almost
        // equal normals can even swap order along a ray. References are
        // therefore classified against non-axis planes with extents fattened
        // by more than that error, so a triangle within it of a plane sits on
        // both sides. Axis planes are exact (the crossing is monotonic in the
        // plane position), as in the kd-tree, and need no fattening.
        eps_ = robust_epsilon(tris);
        strategy_ = make_strategy(opt);
    }

    // `credit` and `nodes`: the memory budget and the node allocator of the
    // build task (thread) running this node.
    BuildNode* build(NodeRefs refs, Cell cell, int depth, double budget, uint64_t id,
                     TaskCredit& credit, NodeArena::Local& nodes) {
        check_stop();
        const size_t n = refs.refs.size();
        const double area = cell.area();
        if (int(n) <= opt_.leaf_size || depth >= opt_.max_depth || !(area > 0))
            return leaf(refs, area, depth, credit, nodes);

        // Fast quality bins the candidates of big nodes (SweepBins) and
        // sweeps every projection below them.
        const bool binned =
            opt_.build_quality == BuildQuality::Fast && n >= size_t(std::max(opt_.fast_min_refs, 0));

        // The node's scratch space while it looks for a plane: its triangle
        // ids, the sweeps' position arrays with their sort's room and the
        // positions kept before the middle (at most one per event; per
        // thread; a binned node's bins instead, per direction and chunk),
        // BSP_IZE's reference BVH.
        const uint64_t sweep_bytes =
            binned ? binned_scratch_bytes(n)
                   : uint64_t(n) * (4 * sizeof(float) + 2 * sizeof(SweepStop)) *
                         uint64_t(threads_);
        Charge scratch(credit,
                       uint64_t(n) * (sizeof(uint32_t) +
                                      (strategy_->tries_triangle_planes() ? kIzeBytesPerRef : 0)) +
                           sweep_bytes,
                       depth, "a node's sweep buffers");
        Rng rng(Rng::mix(opt_.seed, id));
        std::vector<Vec3> dirs;
        {
            // Freed before the children are built: recursion would hold it per level.
            std::vector<uint32_t> tri_ids(n);
            for (size_t i = 0; i < n; ++i) tri_ids[i] = refs.refs[i].tri;
            node_directions(*strategy_, opt_, tris_, tri_ids.data(), n, rng, dirs);
        }

        // BSP_IZE's triangle planes are one more task beside the directions,
        // handed out first (the longest): run after the sweeps, the big
        // nodes' ize_planes kept one of two threads idle. It alone draws
        // from rng, so the tree is the same whenever it runs.
        const bool ize = strategy_->tries_triangle_planes();
        SweepResult total, ize_result;
        std::vector<SweepResult> per_dir(dirs.size());
        // A direction's sweep starts from a bound, not from an infinite
        // cost: a candidate at or above the leaf's limit cannot make a
        // split (the fallback is tried only when the best is not below the
        // limit, and must be below it too), and in the serial sweeps one
        // at or above the best of the directions before it cannot win
        // either (merged in direction order, the earlier wins a tie). So
        // the sweep prices fewer candidates' areas, and the node's split
        // is the same. The parallel sweeps start from the limit alone, so
        // the trees do not depend on the threads.
        const float limit = cost_.split_limit(n);
        SweepResult bound;
        bound.best.cost = limit;
        bound.fallback.cost = limit;
        // In parallel, BSP_IZE's planes are the first task (the longest);
        // in series the last, from the directions' best (merged after them,
        // they win only below it).
        auto task_range = [&](size_t b, size_t e) {
            for (size_t j = b; j < e; ++j) {
                if (ize && j == 0) ize_result = ize_planes(refs, cell, area, rng, bound);
                else per_dir[j - ize] = sweep(refs, cell, area, dirs[j - ize], bound);
            }
        };
        const size_t tasks = dirs.size() + ize;
        if (binned) {
            binned_sweep(refs, cell, area, dirs, per_dir);
            if (ize) ize_result = ize_planes(refs, cell, area, rng, bound);
        } else if (threads_ > 1 && n > kParallelDirections) {
            parallel_for(tasks, 1, threads_, task_range);
        } else {
            SweepResult start = bound;
            for (size_t j = 0; j < dirs.size(); ++j) {
                per_dir[j] = sweep(refs, cell, area, dirs[j], start);
                merge(start, per_dir[j]);
            }
            if (ize) ize_result = ize_planes(refs, cell, area, rng, start);
        }
        for (const SweepResult& r : per_dir) merge(total, r);  // fixed order: deterministic
        if (ize) merge(total, ize_result);

        Candidate s = total.best;
        if (!(s.cost < limit)) s = total.fallback;  // Ize et al.'s retry at a constant cost
        if (!(s.cost < limit)) return leaf(refs, area, depth, credit, nodes);
        const double total_refs = double(s.n_left) + double(s.n_right);
        if (total_refs > budget) return leaf(refs, area, depth, credit, nodes);

        // The children's references are charged before they are made, their
        // clipped polygons (whose size the split decides) as soon as they are.
        scratch.reset();
        NodeRefs left, right;
        {
            Charge work(credit, sizeof(Ref) * (uint64_t(s.n_left) + s.n_right) + kBuildNodeBytes,
                        depth, "the children's references");
            left.charge = work.take(sizeof(Ref) * s.n_left);
            right.charge = work.take(sizeof(Ref) * s.n_right);
            work.keep();  // this node
        }
        left.refs.reserve(s.n_left);
        right.refs.reserve(s.n_right);
        split_refs(refs, s, left, right);
        refs = NodeRefs();  // the children have their own copies now
        {
            // What the children hold beyond their charged references.
            auto owed = [](const NodeRefs& r) {
                const uint64_t held =
                    r.refs.capacity() * sizeof(Ref) + r.pool.capacity() * sizeof(Vec3);
                return held > r.charge.bytes() ? held - r.charge.bytes() : 0;
            };
            const uint64_t lpool = owed(left);
            Charge pools(credit, lpool + owed(right), depth, "the clipped polygons");
            left.charge.absorb(pools.take(lpool));
            right.charge.absorb(std::move(pools));
        }
        Cell lcell, rcell;
        cell.split(Vec3d(s.dir), double(s.pos), lcell, rcell);
        cell = Cell();

        BuildNode* node = nodes.make<BuildNode>();
        node->area = float(area);
        int axis;
        if (s.kd && is_axis(s.dir, axis)) {
            node->kind = kd_kind(axis);
            node->split = s.pos;
        } else {
            node->kind = NodeKind::General;
            node->plane = {s.dir.x, s.dir.y, s.dir.z, s.pos};
        }
        double lbudget, rbudget;
        split_budget(budget, s.n_left, s.n_right, lbudget, rbudget);
        const uint64_t lid = Rng::mix(id, 1), rid = Rng::mix(id, 2);
        if (spawns(n, std::min(s.n_left, s.n_right))) {
            auto right_task = spawn([&, r = std::move(right), c = std::move(rcell)]() mutable {
                TaskCredit task_credit(memory_);
                NodeArena::Local task_nodes(arena_);
                r.charge.move_to(task_credit);
                return build(std::move(r), std::move(c), depth + 1, rbudget, rid, task_credit,
                             task_nodes);
            });
            node->child[0] = build(std::move(left), std::move(lcell), depth + 1, lbudget, lid,
                                   credit, nodes);
            node->child[1] = right_task.get();
        } else {
            node->child[0] = build(std::move(left), std::move(lcell), depth + 1, lbudget, lid,
                                   credit, nodes);
            node->child[1] = build(std::move(right), std::move(rcell), depth + 1, rbudget, rid,
                                   credit, nodes);
        }
        return node;
    }

private:
    std::unique_ptr<DirectionStrategy> strategy_;
    float eps_ = 0;  // the fattening of extents along non-axis directions

    const Vec3* verts(const NodeRefs& nr, const Ref& r, uint32_t& count) const {
        if (r.count == 0) {
            count = 3;
            return tris_[r.tri].v;
        }
        count = r.count;
        return &nr.pool[r.first];
    }

    // The reference's extent along u, fattened by eps_ unless u is an axis.
    void extent(const NodeRefs& nr, const Ref& r, const Vec3& u, bool axis, float& lo,
                float& hi) const {
        uint32_t c;
        const Vec3* v = verts(nr, r, c);
        lo = hi = proj(u, v[0]);
        for (uint32_t i = 1; i < c; ++i) {
            const float x = proj(u, v[i]);
            lo = std::min(lo, x);
            hi = std::max(hi, x);
        }
        if (!axis) lo -= eps_, hi += eps_;
    }

    BuildNode* leaf(const NodeRefs& nr, double area, int depth, TaskCredit& credit,
                    NodeArena::Local& nodes) const {
        const size_t n = nr.refs.size();
        Charge(credit, leaf_bytes(opt_, n), depth, "a leaf").keep();
        BuildNode* node = nodes.make<BuildNode>();
        node->area = float(area);
        const bool clipped = opt_.leaf_boxes == LeafBoxes::Clipped;
        node->count = uint32_t(n);
        node->refs = nodes.array<uint32_t>(n);
        if (clipped) node->ref_boxes = nodes.array<Box>(n);
        // The references in triangle order: their indices sorted in the
        // leaf's own list, each then replaced by its triangle (a triangle
        // has one reference per node, so the order has no ties).
        uint32_t* order = node->refs;
        for (size_t i = 0; i < n; ++i) order[i] = uint32_t(i);
        std::sort(order, order + n,
                  [&](uint32_t a, uint32_t b) { return nr.refs[a].tri < nr.refs[b].tri; });
        for (size_t k = 0; k < n; ++k) {
            const uint32_t i = order[k];
            node->refs[k] = nr.refs[i].tri;
            if (!clipped) continue;
            // The clipped polygon's box, padded like the fattened extents.
            uint32_t c;
            const Vec3* v = verts(nr, nr.refs[i], c);
            Box b;
            for (uint32_t j = 0; j < c; ++j) b.extend(v[j]);
            const Vec3 pad(eps_, eps_, eps_);
            node->ref_boxes[k] = {b.lo - pad, b.hi + pad};
        }
        report_leaf(progress_, depth);
        return node;
    }

    static void merge(SweepResult& into, const SweepResult& r) {
        if (r.best.cost < into.best.cost) into.best = r.best;
        if (r.fallback.cost < into.fallback.cost) into.fallback = r.fallback;
    }

    // Offers one candidate plane (counts given) to the result: at the cost
    // model's step, and under ^Kd a general plane at its fallback step too.
    // A candidate replaces the best with a lower cost, or with an equal one
    // when `tie_best` / `tie_fb` says it comes first (below).
    void offer(SweepResult& res, const Vec3& u, bool kd, float p, bool planar_left, uint32_t l,
               uint32_t r, double below, double above, double inv_area, size_t n,
               bool tie_best = false, bool tie_fb = false) const {
        const double p_below = below * inv_area, p_above = above * inv_area;
        const float cost = cost_.split(cost_.step(kd, n), p_below, l, p_above, r);
        if (beats(cost, res.best.cost, tie_best)) res.best = {u, p, planar_left, kd, cost, l, r};
        if (cost_.has_fallback(kd)) {
            const float fb = cost_.split(cost_.fallback_step(), p_below, l, p_above, r);
            if (beats(fb, res.fallback.cost, tie_fb)) res.fallback = {u, p, planar_left, kd, fb, l, r};
        }
    }

    // Whether a cost (or a bound on one) takes the place of `current`: below
    // it, or equal to it when the candidate wins a tie.
    static bool beats(float cost, float current, bool tie) {
        return cost < current || (tie && cost == current);
    }

    // Whether a candidate with nl references below and nr above (those in
    // the plane not yet counted) can beat the best so far or the fallback:
    // if not, its areas need not be computed.
    bool may_win(const SweepResult& res, bool kd, size_t n, uint32_t nl, uint32_t nr,
                 bool tie_best = false, bool tie_fb = false) const {
        if (beats(cost_.lower_bound(cost_.step(kd, n), nl, nr), res.best.cost, tie_best))
            return true;
        return cost_.has_fallback(kd) &&
               beats(cost_.lower_bound(cost_.fallback_step(), nl, nr), res.fallback.cost, tie_fb);
    }

    // Two more bounds, from a candidate already priced on the side that
    // holds more references. The part of a convex cell below a plane grows
    // as the plane rises, and so does its surface (each face's clipped area
    // does), and the part above shrinks. So a candidate beyond a priced one
    // has p_below at least that one's, and a candidate before it has
    // p_above at least that one's. With p_below + p_above >= 1, the
    // weighted count is then at least b nl + (1 - b) nr for p_below >= b
    // when nl >= nr (may_win_beyond), and (1 - a) nl + a nr for p_above >= a
    // when nl < nr (may_win_before). 1e-7 of each probability absorbs the
    // areas' rounding (about 1e-14 of the cell's), and the cost's float
    // arithmetic is monotone, so no candidate skipped here could have won.
    bool may_win_beyond(const SweepResult& res, bool kd, size_t n, uint32_t nl, uint32_t nr,
                        double p_below_min) const {
        if (nl < nr) return true;  // the lower bound is nl: may_win's already
        const double b = std::clamp(p_below_min, 0.0, 1.0);
        return may_win_weighted(res, kd, n, nl, nr, b, 1.0 - b, false, false);
    }
    bool may_win_before(const SweepResult& res, bool kd, size_t n, uint32_t nl, uint32_t nr,
                        double p_above_min, bool tie_best, bool tie_fb) const {
        if (nl >= nr) return true;
        const double a = std::clamp(p_above_min, 0.0, 1.0);
        return may_win_weighted(res, kd, n, nl, nr, 1.0 - a, a, tie_best, tie_fb);
    }
    static constexpr double kAreaMargin = 1e-7;
    bool may_win_weighted(const SweepResult& res, bool kd, size_t n, uint32_t nl, uint32_t nr,
                          double pb, double pa, bool tie_best, bool tie_fb) const {
        const double m = kAreaMargin;
        if (beats(cost_.split(cost_.step(kd, n), pb - m, nl, pa - m, nr), res.best.cost, tie_best))
            return true;
        return cost_.has_fallback(kd) &&
               beats(cost_.split(cost_.fallback_step(), pb - m, nl, pa - m, nr), res.fallback.cost,
                     tie_fb);
    }

    // A candidate position before a sweep's middle, counted and kept to be
    // priced backwards: nl references below it (those in the plane not
    // counted), nr above, np in the plane.
    struct SweepStop {
        float p;
        uint32_t nl, nr, np;
    };

    // Per-thread buffers: sweeps run millions of times on small nodes. The
    // thread_local is found once per sweep, through this call kept out of
    // line: in a shared library each use of one is a look-up
    // (__tls_get_addr), and inlined the compiler repeated it at every
    // push_back, 6 % of a build.
    struct SweepScratch {
        std::vector<float> starts, ends, planars, sort_tmp;
        std::vector<SweepStop> stops;
        CellProjection cp;
    };
    [[gnu::noinline]] static SweepScratch& sweep_scratch() {
        thread_local SweepScratch scratch;
        return scratch;
    }

    // `start`: the costs a candidate must beat (no plane of their own).
    //
    // The result is that of pricing every position in order and keeping the
    // first of the cheapest, but the positions are priced from the middle
    // outwards, so that both halves have a bound from a priced neighbour
    // (may_win_before, may_win_beyond). The middle is the first position
    // with at least as many references below as above. There the positions
    // before it are priced backwards, each one earlier than every candidate
    // priced so far, so it wins a tie against the sweep's own best (not
    // against `start`, which belongs to an earlier direction). The rest are
    // priced in order.
    SweepResult sweep(const NodeRefs& nr, const Cell& cell, double area, const Vec3& u,
                      const SweepResult& start) const {
        SweepResult res;
        res.best.cost = start.best.cost;
        res.fallback.cost = start.fallback.cost;
        const size_t n = nr.refs.size();
        SweepScratch& scratch = sweep_scratch();
        auto& [starts, ends, planars, sort_tmp, stops, cp] = scratch;
        starts.clear();
        ends.clear();
        planars.clear();
        stops.clear();
        int axis;
        const bool is_ax = is_axis(u, axis);
        for (const Ref& r : nr.refs) {
            float lo, hi;
            extent(nr, r, u, is_ax, lo, hi);
            if (lo == hi) {
                planars.push_back(lo);
            } else {
                starts.push_back(lo);
                ends.push_back(hi);
            }
        }
        sort_projections(starts, sort_tmp);
        sort_projections(ends, sort_tmp);
        sort_projections(planars, sort_tmp);

        cp.project(cell, Vec3d(u));  // re-projected, it keeps its arrays
        const double clo = cp.lo(), chi = cp.hi();
        const bool kd = opt_.kd_nodes && is_ax;
        const double inv_area = 1.0 / area;
        // Few candidates: evaluate the areas directly; many: tabulate once.
        if (2 * n > 2 * cp.breaks_estimate()) cp.tabulate();
        const bool monotone = cp.areas_monotone();
        // Whether a plane at p is a candidate at all. On an axis, triangles
        // lying in the cell's own face (walls, floors) can be cut off into a
        // flat cell, as in the kd builder.
        auto at_lo = [&](float p, uint32_t np) {
            return is_ax && np > 0 && double(p) == clo && chi > clo;
        };
        auto at_hi = [&](float p, uint32_t np) {
            return is_ax && np > 0 && double(p) == chi && chi > clo;
        };

        // The positions before the middle, kept as they are counted, priced
        // backwards. Returns p_below of the last position (in order) priced:
        // a bound for the positions after them.
        auto price_backwards = [&]() {
            double p_above_min = 0, p_below_last = 0;
            bool priced = false;
            for (size_t i = stops.size(); i-- > 0;) {
                const SweepStop& st = stops[i];
                const float p = st.p;
                const uint32_t nl = st.nl, nr_ = st.nr, np = st.np;
                bool tie_best = res.best.cost < start.best.cost;
                bool tie_fb = res.fallback.cost < start.fallback.cost;
                if (!may_win(res, kd, n, nl, nr_, tie_best, tie_fb)) continue;
                if (monotone && !may_win_before(res, kd, n, nl, nr_, p_above_min, tie_best, tie_fb))
                    continue;
                double below, above;
                cp.eval(double(p), below, above);
                p_above_min = above * inv_area;
                if (!priced) p_below_last = below * inv_area, priced = true;
                // In order, the plane's references go below first; so last here.
                if (np && !at_lo(p, np))
                    offer(res, u, kd, p, false, nl, nr_ + np, below, above, inv_area, n, tie_best,
                          tie_fb);
                tie_best = res.best.cost < start.best.cost;
                tie_fb = res.fallback.cost < start.fallback.cost;
                if (!at_hi(p, np))
                    offer(res, u, kd, p, true, nl + np, nr_, below, above, inv_area, n, tie_best,
                          tie_fb);
            }
            return p_below_last;
        };

        uint32_t nl = 0, nr_ = uint32_t(n);
        bool before_middle = true;
        double p_below_min = 0;  // p_below of the last candidate priced
        size_t is = 0, ie = 0, ip = 0;
        while (is < starts.size() || ie < ends.size() || ip < planars.size()) {
            float p = kInf;
            if (is < starts.size()) p = std::min(p, starts[is]);
            if (ie < ends.size()) p = std::min(p, ends[ie]);
            if (ip < planars.size()) p = std::min(p, planars[ip]);
            uint32_t ne = 0, np = 0, ns = 0;
            while (ie < ends.size() && ends[ie] == p) ++ne, ++ie;
            while (ip < planars.size() && planars[ip] == p) ++np, ++ip;
            while (is < starts.size() && starts[is] == p) ++ns, ++is;
            nr_ -= np + ne;
            const bool lo_face = at_lo(p, np), hi_face = at_hi(p, np);
            if (cp.cuts(double(p)) || lo_face || hi_face) {
                if (before_middle && nl < nr_) {
                    stops.push_back({p, nl, nr_, np});
                } else if (before_middle) {
                    p_below_min = price_backwards();
                    before_middle = false;
                }
                if (!before_middle && may_win(res, kd, n, nl, nr_) &&
                    (!monotone || may_win_beyond(res, kd, n, nl, nr_, p_below_min))) {
                    double below, above;
                    cp.eval(double(p), below, above);
                    p_below_min = below * inv_area;
                    if (!hi_face)
                        offer(res, u, kd, p, true, nl + np, nr_, below, above, inv_area, n);
                    if (np && !lo_face)
                        offer(res, u, kd, p, false, nl, nr_ + np, below, above, inv_area, n);
                }
            }
            nl += ns + np;
        }
        if (before_middle) price_backwards();
        return res;
    }

    // The bins of a binned node, per direction and per chunk of references
    // counted apart (an upper bound: directions may be fewer than k + 3).
    uint64_t binned_scratch_bytes(size_t n) const {
        const uint64_t chunks = n > kParallelDirections && threads_ > 1 ? (n + kBinChunk - 1) / kBinChunk : 1;
        const uint64_t bins = uint64_t(std::max(sweep_bins(n, opt_.fast_bins), 2));
        const uint64_t per_dir = bins * (sizeof(float) + 2 * sizeof(uint32_t)) +
                                 sizeof(SweepBins) + sizeof(CellProjection);
        return chunks * uint64_t(opt_.k + 3) * per_dir;
    }

    // The fast build quality's sweep of a big node: every direction's
    // candidates are the inner boundaries of sweep_bins() equal bins over the
    // cell's extent (SweepBins), priced with the same areas and cost model
    // as the exact sweep. One pass over the references projects each on all
    // directions (its polygon is read once); big nodes count chunks of
    // references on several threads and add the counts.
    void binned_sweep(const NodeRefs& nr, const Cell& cell, double area,
                      const std::vector<Vec3>& dirs, std::vector<SweepResult>& out) const {
        const size_t n = nr.refs.size(), k = dirs.size();
        std::vector<CellProjection> cps(k);
        std::vector<uint8_t> axis_dir(k);
        std::vector<SweepBins> proto(k);
        for (size_t j = 0; j < k; ++j) {
            int axis;
            axis_dir[j] = is_axis(dirs[j], axis);
            cps[j].project(cell, Vec3d(dirs[j]));
            proto[j].reset(cps[j].lo(), cps[j].hi(), sweep_bins(n, opt_.fast_bins));
        }
        auto count = [&](size_t b, size_t e, std::vector<SweepBins>& bins) {
            for (size_t i = b; i < e; ++i) {
                uint32_t c;
                const Vec3* v = verts(nr, nr.refs[i], c);
                for (size_t j = 0; j < k; ++j) {
                    const Vec3& u = dirs[j];
                    float lo = proj(u, v[0]), hi = lo;
                    for (uint32_t q = 1; q < c; ++q) {
                        const float x = proj(u, v[q]);
                        lo = std::min(lo, x);
                        hi = std::max(hi, x);
                    }
                    if (!axis_dir[j]) lo -= eps_, hi += eps_;  // as extent() fattens
                    bins[j].add(lo, hi);
                }
            }
        };
        std::vector<SweepBins> bins = proto;
        if (threads_ > 1 && n > kParallelDirections) {
            const size_t chunks = (n + kBinChunk - 1) / kBinChunk;
            std::vector<std::vector<SweepBins>> part(chunks, proto);
            parallel_for(n, kBinChunk, threads_, [&](size_t b, size_t e) {
                check_stop();
                count(b, e, part[b / kBinChunk]);
            });
            for (const auto& p : part)
                for (size_t j = 0; j < k; ++j) bins[j].merge(p[j]);
        } else {
            count(0, n, bins);
        }

        const double inv_area = 1.0 / area;
        for (size_t j = 0; j < k; ++j) {
            SweepResult& res = out[j];
            const Vec3& u = dirs[j];
            const CellProjection& cp = cps[j];
            const bool kd = opt_.kd_nodes && axis_dir[j];
            const bool monotone = cp.areas_monotone();
            double p_below_min = 0;
            bins[j].for_each_boundary(uint32_t(n), [&](float p, uint32_t nl, uint32_t nr_) {
                if (!cp.cuts(double(p)) || !may_win(res, kd, n, nl, nr_)) return;
                if (monotone && !may_win_beyond(res, kd, n, nl, nr_, p_below_min)) return;
                double below, above;
                cp.areas_at(double(p), below, above);
                p_below_min = below * inv_area;
                offer(res, u, kd, p, true, nl, nr_, below, above, inv_area, n);
            });
        }
    }

    // BSP_IZE's extra candidates: for (at most ize_candidates) triangles of the
    // node, the triangle's own plane and the three planes through its edges
    // perpendicular to it. They are not swept; a bounding-volume hierarchy
    // over the references counts each side in about O(sqrt n).
    SweepResult ize_planes(const NodeRefs& nr, const Cell& cell, double area, Rng& rng,
                           const SweepResult& start) const;

    void split_refs(const NodeRefs& nr, const Candidate& s, NodeRefs& left,
                    NodeRefs& right) const {
        const Vec3& u = s.dir;
        int axis;
        const bool is_ax = is_axis(u, axis);
        // Per thread: a build splits references at every node. Bound once:
        // in a shared library each use of a thread_local is a look-up.
        thread_local std::vector<Vec3> below_buf, above_buf;
        std::vector<Vec3>& below = below_buf;
        std::vector<Vec3>& above = above_buf;
        for (const Ref& r : nr.refs) {
            float lo, hi;
            extent(nr, r, u, is_ax, lo, hi);
            int side;  // -1 left only, 1 right only, 0 both
            if (lo == hi) side = (lo < s.pos || (lo == s.pos && s.planar_left)) ? -1 : 1;
            else if (hi <= s.pos) side = -1;
            else if (lo >= s.pos) side = 1;
            else side = 0;
            if (side != 0) {
                copy_ref(nr, r, side < 0 ? left : right);
                continue;
            }
            uint32_t c;
            const Vec3* v = verts(nr, r, c);
            split_polygon(v, c, u, s.pos, below, above);
            // Rounding can empty a half of a polygon the plane really cuts:
            // then the whole polygon stands in, which is merely conservative.
            push_polygon(left, r.tri, below.size() >= 3 ? below.data() : v,
                         below.size() >= 3 ? uint32_t(below.size()) : c);
            push_polygon(right, r.tri, above.size() >= 3 ? above.data() : v,
                         above.size() >= 3 ? uint32_t(above.size()) : c);
        }
    }

    static void copy_ref(const NodeRefs& from, const Ref& r, NodeRefs& to) {
        if (r.count == 0) {
            to.refs.push_back(r);
            return;
        }
        to.refs.push_back({r.tri, uint32_t(to.pool.size()), r.count});
        to.pool.insert(to.pool.end(), from.pool.begin() + r.first,
                       from.pool.begin() + r.first + r.count);
    }

    static void push_polygon(NodeRefs& to, uint32_t tri, const Vec3* v, uint32_t c) {
        to.refs.push_back({tri, uint32_t(to.pool.size()), c});
        to.pool.insert(to.pool.end(), v, v + c);
    }

    static void split_polygon(const Vec3* v, uint32_t c, const Vec3& u, float pos,
                              std::vector<Vec3>& below, std::vector<Vec3>& above) {
        below.clear();
        above.clear();
        for (uint32_t i = 0; i < c; ++i) {
            const Vec3& a = v[i];
            const Vec3& b = v[(i + 1) % c];
            const float pa = proj(u, a), pb = proj(u, b);
            if (pa <= pos) below.push_back(a);
            if (pa >= pos) above.push_back(a);
            if ((pa < pos && pb > pos) || (pa > pos && pb < pos)) {
                // Interpolate in double; the new vertex lies on the plane.
                const double t = (double(pos) - pa) / (double(pb) - pa);
                const Vec3 x(float(a.x + (double(b.x) - a.x) * t), float(a.y + (double(b.y) - a.y) * t),
                             float(a.z + (double(b.z) - a.z) * t));
                below.push_back(x);
                above.push_back(x);
            }
        }
    }
};

// ---- BSP_IZE ---------------------------------------------------------------

// A small BVH over the node's references: boxes of their clipped polygons.
struct RefBvh {
    struct Node {
        Box box;
        uint32_t begin, end;  // range in order[]
        uint32_t child = 0;   // first child index (0: leaf)
    };
    std::vector<Node> nodes;
    std::vector<uint32_t> order;
};

// Counts, for the plane u.x = d: references only below, only above, crossing,
// and lying exactly in it - with the classification split_refs() applies.
struct PlaneCount {
    uint32_t below = 0, above = 0, both = 0, planar = 0;
};

// The planes a BSP_IZE node has tried, as their bits: an open-addressing
// set sized for the node's planes at most half full, reused per thread.
class PlaneSet {
public:
    void reset(size_t planes) {
        size_t cap = 16;
        while (cap < 2 * planes) cap *= 2;
        keys_.assign(cap, Key{kEmpty, 0, 0, 0});
        mask_ = cap - 1;
    }
    // False if the plane was in the set already.
    bool insert(const Vec3& u, float d) {
        const Key k{std::bit_cast<uint32_t>(u.x), std::bit_cast<uint32_t>(u.y),
                    std::bit_cast<uint32_t>(u.z), std::bit_cast<uint32_t>(d)};
        uint64_t h = (uint64_t(k.x) << 32 | k.y) * 0x9E3779B97F4A7C15ull ^
                     (uint64_t(k.z) << 32 | k.d) * 0xC2B2AE3D27D4EB4Full;
        h ^= h >> 29;
        for (size_t i = size_t(h) & mask_;; i = (i + 1) & mask_) {
            Key& slot = keys_[i];
            if (slot.x == kEmpty) {
                slot = k;
                return true;
            }
            if (slot.x == k.x && slot.y == k.y && slot.z == k.z && slot.d == k.d) return false;
        }
    }

private:
    struct Key {
        uint32_t x, y, z, d;
    };
    // A NaN's bits: no unit normal has them.
    static constexpr uint32_t kEmpty = 0xFFFFFFFFu;
    std::vector<Key> keys_;
    size_t mask_ = 0;
};

[[gnu::noinline]] PlaneSet& plane_set() {
    thread_local PlaneSet set;
    return set;
}

SweepResult BspBuilder::ize_planes(const NodeRefs& nr, const Cell& cell, double area,
                                   Rng& rng, const SweepResult& start) const {
    SweepResult res;
    res.best.cost = start.best.cost;
    res.fallback.cost = start.fallback.cost;
    const size_t n = nr.refs.size();
    // Reference boxes and a median-split BVH over them.
    std::vector<Box> boxes(n);
    std::vector<Vec3> centre(n);
    for (size_t i = 0; i < n; ++i) {
        uint32_t c;
        const Vec3* v = verts(nr, nr.refs[i], c);
        for (uint32_t j = 0; j < c; ++j) boxes[i].extend(v[j]);
        centre[i] = (boxes[i].lo + boxes[i].hi) * 0.5f;
    }
    RefBvh bvh;
    bvh.order.resize(n);
    for (size_t i = 0; i < n; ++i) bvh.order[i] = uint32_t(i);
    bvh.nodes.push_back({Box(), 0, uint32_t(n)});
    for (size_t k = 0; k < bvh.nodes.size(); ++k) {
        RefBvh::Node& node = bvh.nodes[k];
        Box b, cb;
        for (uint32_t i = node.begin; i < node.end; ++i) {
            b.extend(boxes[bvh.order[i]]);
            cb.extend(centre[bvh.order[i]]);
        }
        bvh.nodes[k].box = b;
        if (node.end - node.begin <= 4) continue;
        const Vec3 ext = cb.hi - cb.lo;
        const int axis = ext.x > ext.y ? (ext.x > ext.z ? 0 : 2) : (ext.y > ext.z ? 1 : 2);
        const uint32_t mid = (node.begin + node.end) / 2;
        std::nth_element(bvh.order.begin() + node.begin, bvh.order.begin() + mid,
                         bvh.order.begin() + node.end, [&](uint32_t a, uint32_t c) {
                             return centre[a][axis] < centre[c][axis];
                         });
        const uint32_t begin = node.begin, end = node.end;
        bvh.nodes[k].child = uint32_t(bvh.nodes.size());
        bvh.nodes.push_back({Box(), begin, mid});
        bvh.nodes.push_back({Box(), mid, end});
    }

    // `hopeless(l, r)`: whether a plane with at least l references below
    // and r above can no longer win; the walk then gives up (false).
    auto count = [&](const Vec3& u, bool is_ax, float d, auto&& hopeless, PlaneCount& pc) {
        auto ruled_out = [&] { return hopeless(pc.below + pc.both, pc.above + pc.both); };
        const Vec3d ud(u);
        // Box projections are conservative by a relative margin, so a whole
        // subtree is counted at once only when every reference in it is
        // certainly on that side in the float projection split_refs() uses.
        uint32_t stack[kRefBvhStack];
        int top = 0;
        stack[top++] = 0;
        while (top) {
            const RefBvh::Node& node = bvh.nodes[stack[--top]];
            const Vec3d c(Vec3((node.box.lo + node.box.hi) * 0.5f));
            const Vec3d e(Vec3((node.box.hi - node.box.lo) * 0.5f));
            const double mid = dot(ud, c);
            const double rad = std::fabs(ud.x) * e.x + std::fabs(ud.y) * e.y + std::fabs(ud.z) * e.z;
            const double margin = 1e-5 * (std::fabs(mid) + rad) + 2.0 * eps_ + 1e-30;
            if (mid + rad + margin < d) {
                pc.below += node.end - node.begin;
                if (ruled_out()) return false;
                continue;
            }
            if (mid - rad - margin > d) {
                pc.above += node.end - node.begin;
                if (ruled_out()) return false;
                continue;
            }
            if (node.child && top + 2 <= kRefBvhStack) {
                stack[top++] = node.child;
                stack[top++] = node.child + 1;
                continue;
            }
            for (uint32_t i = node.begin; i < node.end; ++i) {
                float lo, hi;
                extent(nr, nr.refs[bvh.order[i]], u, is_ax, lo, hi);
                if (lo == hi && lo == d) ++pc.planar;
                else if (hi <= d) ++pc.below;
                else if (lo >= d) ++pc.above;
                else ++pc.both;
            }
            if (ruled_out()) return false;
        }
        return true;
    };

    const double inv_area = 1.0 / area;
    CellProjection cp;  // re-projected per direction, its arrays kept
    // The direction cp sees the cell along: a triangle's own plane is tried
    // at both ends of its extent, and neighbouring triangles (a quad's two,
    // a wall's) share a normal, so consecutive planes often need the same
    // projection.
    Vec3 projected;
    bool has_projection = false;
    // A plane tried before in this node is skipped: its counts and areas,
    // so its cost, would be the same, and a candidate replaces the best
    // only when strictly cheaper. Coplanar neighbours (a quad's two
    // triangles, a wall's, a voxel scene's faces) share their planes.
    PlaneSet& tried = plane_set();
    auto try_plane = [&](const Vec3& u, float d) {
        if (!tried.insert(u, d)) return;
        int axis;
        const bool is_ax = is_axis(u, axis);
        const bool kd = opt_.kd_nodes && is_ax;
        // Bit for bit: a canonical normal's zero components can be -0.
        auto bits = [](float x) { return std::bit_cast<uint32_t>(x); };
        if (!has_projection || bits(u.x) != bits(projected.x) || bits(u.y) != bits(projected.y) ||
            bits(u.z) != bits(projected.z)) {
            cp.project(cell, Vec3d(u));
            projected = u;
            has_projection = true;
        }
        if (!cp.cuts(double(d))) return;
        double below, above;
        cp.areas_at(double(d), below, above);
        const double p_below = below * inv_area, p_above = above * inv_area;
        // With the areas known, the counts so far bound the plane's cost:
        // it only grows with them (and with both sides taken, no bonus).
        // A rounded area below zero (a sliver face) would break that, so
        // such a plane is always counted to the end.
        const bool bounded = p_below >= 0 && p_above >= 0;
        auto hopeless = [&](uint32_t l, uint32_t r) {
            return bounded && l != 0 && r != 0 &&
                   !may_win_weighted(res, kd, n, l, r, p_below, p_above, false, false);
        };
        PlaneCount pc;
        if (!count(u, is_ax, d, hopeless, pc)) return;
        const uint32_t l = pc.below + pc.both, r = pc.above + pc.both;
        // Planar references first join the left (as split_refs() with planar_left).
        offer(res, u, kd, d, true, l + pc.planar, r, below, above, inv_area, n);
        if (pc.planar) offer(res, u, kd, d, false, l, r + pc.planar, below, above, inv_area, n);
    };

    // Candidate triangles: all of them in small nodes, a seeded sample in big ones.
    std::vector<uint32_t> pick;
    if (n <= size_t(opt_.ize_candidates)) {
        for (size_t i = 0; i < n; ++i) pick.push_back(uint32_t(i));
    } else {
        for (int j = 0; j < opt_.ize_candidates; ++j) pick.push_back(uint32_t(rng.below(n)));
        std::sort(pick.begin(), pick.end());
        pick.erase(std::unique(pick.begin(), pick.end()), pick.end());
    }
    tried.reset(5 * pick.size());
    for (uint32_t i : pick) {
        const Triangle& t = tris_[nr.refs[i].tri];
        const Vec3 nt = unit_normal(t);
        // The triangle's own plane, placed just beyond either end of its
        // (fattened) extent so the triangle itself lies wholly on one side.
        int axis;
        const float fat = is_axis(nt, axis) ? 0.0f : eps_;
        float lo = proj(nt, t.v[0]), hi = lo;
        for (int j = 1; j < 3; ++j) {
            lo = std::min(lo, proj(nt, t.v[j]));
            hi = std::max(hi, proj(nt, t.v[j]));
        }
        try_plane(nt, lo - fat);
        if (hi + fat != lo - fat) try_plane(nt, hi + fat);
        // The planes through each edge, perpendicular to the triangle: placed
        // at the edge's outer end so the triangle is wholly inside.
        for (int j = 0; j < 3; ++j) {
            const Vec3& a = t.v[j];
            const Vec3& b = t.v[(j + 1) % 3];
            const Vec3& c = t.v[(j + 2) % 3];
            const Vec3 raw = cross(b - a, nt);
            if (raw.x == 0 && raw.y == 0 && raw.z == 0) continue;
            const Vec3 ne = canonical(raw);
            const float pa = proj(ne, a), pb = proj(ne, b), pc = proj(ne, c);
            const float efat = is_axis(ne, axis) ? 0.0f : eps_;
            try_plane(ne, pc < pa ? std::max(pa, pb) + efat : std::min(pa, pb) - efat);
        }
    }
    return res;
}

}  // namespace

Tree build_bsp_tree(std::vector<Triangle> triangles, const BuildOptions& options,
                    Progress* progress) {
    return run_builder(std::move(triangles), options, [&](Tree& tree, const Prepared& prep,
                                                          MemoryBudget& memory, NodeArena& arena) {
        TaskCredit credit(memory);
        NodeArena::Local nodes(arena);
        NodeRefs refs;
        refs.charge = Charge(credit, sizeof(Ref) * prep.live.size(), 0, "the references");
        refs.refs.reserve(prep.live.size());
        for (uint32_t i : prep.live) refs.refs.push_back({i, 0, 0});
        BspBuilder builder(tree.triangles, tree.options, progress,
                           resolve_threads(options.threads), memory, arena);
        return builder.build(std::move(refs), Cell::from_box(tree.bounds), 0, prep.ref_budget,
                             options.seed, credit, nodes);
    });
}

}  // namespace bsp
