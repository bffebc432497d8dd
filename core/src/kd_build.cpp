// The kd builder of Wald & Havran (2006): the 2N extents of the triangles
// along each axis are sorted once at the root; each node sweeps its sorted
// events to find the cheapest SAH plane, then splits its event lists into the
// children's lists without re-sorting. Only triangles that straddle the plane
// get new events: they are clipped to each child box ("perfect splits"), and
// those few new events are sorted and merged in.
#include "kd_build.hpp"

#include <algorithm>
#include <cmath>
#include <future>
#include <memory>

#include "build_tree.hpp"
#include "clip.hpp"
#include "cost_model.hpp"
#include "parallel.hpp"

namespace bsp {
namespace {

enum EventType : uint32_t { kEnd = 0, kPlanar = 1, kStart = 2 };

// 8 bytes: position plus (triangle << 2 | type). Ends sort before planar
// before starts at equal positions, which the sweep relies on.
struct Event {
    float pos;
    uint32_t key;
    uint32_t tri() const { return key >> 2; }
    uint32_t type() const { return key & 3u; }
    bool operator<(const Event& o) const {
        return pos < o.pos || (pos == o.pos && (key & 3u) < (o.key & 3u));
    }
};

using EventList = std::vector<Event>;

struct NodeEvents {
    EventList axis[3];
    uint32_t count = 0;  // triangles in the node
    Charge charge;       // the lists' bytes in the memory budget
};

// The memory budget's view of a node's event lists: two events per axis per
// triangle at most (a planar one has one), charged before they are filled.
constexpr uint64_t kEventBytesPerRef = 6 * sizeof(Event);
// A triangle straddling a split while the children's lists are made: its
// index and its clipped events on both sides, before they are merged in.
constexpr uint64_t kStraddleBytes = sizeof(uint32_t) + 2 * kEventBytesPerRef;

// A triangle's events along axis k: one planar event, or a start and an end.
void add_axis_events(const Box& b, uint32_t tri, int k, EventList& out) {
    if (b.lo[k] == b.hi[k]) {
        out.push_back({b.lo[k], tri << 2 | kPlanar});
    } else {
        out.push_back({b.lo[k], tri << 2 | kStart});
        out.push_back({b.hi[k], tri << 2 | kEnd});
    }
}

void add_events(const Box& b, uint32_t tri, EventList* out) {
    for (int k = 0; k < 3; ++k) add_axis_events(b, tri, k, out[k]);
}

struct Split {
    int axis = -1;
    float pos = 0;
    bool planar_left = false;
    float cost = kInf;
    uint32_t n_left = 0, n_right = 0;
};

// Nodes with more triangles than this split their three axes in parallel.
constexpr uint32_t kParallelAxes = 1u << 16;

enum Side : uint8_t { kBoth = 0, kLeftOnly = 1, kRightOnly = 2 };

class KdBuilder {
public:
    KdBuilder(const std::vector<Triangle>& tris, const BuildOptions& opt, Progress* progress,
              int threads, MemoryBudget& memory)
        : tris_(tris), opt_(opt), cost_(opt), progress_(progress), threads_(threads),
          memory_(memory) {
        spawn_depth_ = spawn_depth(threads);
    }

    // A build task: the root, or a subtree on a thread of its own.
    std::unique_ptr<BuildNode> build(NodeEvents ev, const Box& box, int depth, double budget) {
        TaskCredit credit(memory_);
        ev.charge.move_to(credit);
        const Charge side_charge(credit, tris_.size(), depth, "a build task's triangle marks");
        std::vector<uint8_t> side(tris_.size());
        return build_node(std::move(ev), box, depth, budget, side, credit);
    }

private:
    const std::vector<Triangle>& tris_;
    const BuildOptions& opt_;
    const CostModel cost_;
    Progress* progress_;
    int threads_;
    int spawn_depth_;
    MemoryBudget& memory_;

    // The cheapest SAH split along axis k, sweeping its sorted events once.
    Split find_split_axis(const NodeEvents& ev, const Box& box, int k) const {
        Split best;
        const Vec3 d = box.hi - box.lo;
        const float parent_area = box.area();
        if (!(parent_area > 0.0f) || !(d[k] > 0.0f)) return best;
        const float inv_area = 1.0f / parent_area;
        const int a = (k + 1) % 3, b = (k + 2) % 3;
        const float cap = d[a] * d[b], rim = d[a] + d[b];
        const EventList& e = ev.axis[k];
        uint32_t nl = 0, nr = ev.count;
        for (size_t i = 0; i < e.size();) {
            const float p = e[i].pos;
            uint32_t ends = 0, planars = 0, starts = 0;
            while (i < e.size() && e[i].pos == p && e[i].type() == kEnd) ++ends, ++i;
            while (i < e.size() && e[i].pos == p && e[i].type() == kPlanar) ++planars, ++i;
            while (i < e.size() && e[i].pos == p && e[i].type() == kStart) ++starts, ++i;
            nr -= planars + ends;
            const bool inside = p > box.lo[k] && p < box.hi[k];
            // On the cell's own face a split can still pay: it cuts the
            // triangles lying in that face (walls, floors) off into a flat
            // cell, so rays crossing the rest of the cell never test them.
            const bool at_lo = p == box.lo[k] && planars > 0;
            const bool at_hi = p == box.hi[k] && planars > 0;
            if (inside || at_lo || at_hi) {
                const float pl = 2.0f * (cap + (p - box.lo[k]) * rim) * inv_area;
                const float pr = 2.0f * (cap + (box.hi[k] - p) * rim) * inv_area;
                for (int planar_left = at_hi ? 0 : 1; planar_left >= (at_lo ? 1 : 0);
                     --planar_left) {
                    uint32_t l = nl + (planar_left ? planars : 0);
                    uint32_t r = nr + (planar_left ? 0 : planars);
                    const float cost = cost_.split(cost_.kd_step(), pl, l, pr, r);
                    if (cost < best.cost) best = {k, p, bool(planar_left), cost, l, r};
                }
            }
            nl += starts + planars;
        }
        return best;
    }

    Split find_split(const NodeEvents& ev, const Box& box) const {
        Split per_axis[3];
        if (threads_ > 1 && ev.count > kParallelAxes) {
            auto a1 = std::async(std::launch::async, [&] { return find_split_axis(ev, box, 1); });
            auto a2 = std::async(std::launch::async, [&] { return find_split_axis(ev, box, 2); });
            per_axis[0] = find_split_axis(ev, box, 0);
            per_axis[1] = a1.get();
            per_axis[2] = a2.get();
        } else {
            for (int k = 0; k < 3; ++k) per_axis[k] = find_split_axis(ev, box, k);
        }
        // Strictly cheaper wins, so ties go to the lower axis whatever the threads.
        Split best = per_axis[0];
        for (int k = 1; k < 3; ++k)
            if (per_axis[k].cost < best.cost) best = per_axis[k];
        return best;
    }

    // Marks every triangle of the node with the side(s) of `s` it lies on.
    void classify(const NodeEvents& ev, const Split& s, std::vector<uint8_t>& side) const {
        for (const Event& e : ev.axis[0])
            if (e.type() != kEnd) side[e.tri()] = kBoth;
        for (const Event& e : ev.axis[s.axis]) {
            const uint32_t t = e.tri();
            if (e.type() == kEnd && e.pos <= s.pos) {
                side[t] = kLeftOnly;
            } else if (e.type() == kStart && e.pos >= s.pos) {
                side[t] = kRightOnly;
            } else if (e.type() == kPlanar) {
                bool left = e.pos < s.pos || (e.pos == s.pos && s.planar_left);
                side[t] = left ? kLeftOnly : kRightOnly;
            }
        }
    }

    // Splits the node's sorted events into the children's sorted events.
    void split_events(NodeEvents& ev, const Split& s, const Box& lbox, const Box& rbox,
                      const std::vector<uint8_t>& side, NodeEvents& left, NodeEvents& right) const {
        std::vector<uint32_t> straddling;
        for (const Event& e : ev.axis[s.axis])
            if (e.type() == kStart && side[e.tri()] == kBoth) straddling.push_back(e.tri());

        EventList new_left[3], new_right[3];
        for (uint32_t t : straddling) {
            Box parent = lbox;
            parent.hi[s.axis] = rbox.hi[s.axis];
            Box lb, rb;
            split_clipped_bounds(tris_[t], parent, s.axis, s.pos, lb, rb);
            // The plane cuts the triangle inside the cell, so both halves are
            // non-empty; rounding can still empty one, and then the whole
            // triangle box (conservative) stands in.
            if (lb.empty()) lb = tris_[t].bounds().intersect(lbox);
            if (rb.empty()) rb = tris_[t].bounds().intersect(rbox);
            add_events(lb, t, new_left);
            add_events(rb, t, new_right);
        }
        left.count = s.n_left;
        right.count = s.n_right;
        auto split_axis = [&](int k) {
            std::sort(new_left[k].begin(), new_left[k].end());
            std::sort(new_right[k].begin(), new_right[k].end());
            const EventList& in = ev.axis[k];
            size_t nl = 0, nr = 0;
            for (const Event& e : in) {
                const uint8_t sd = side[e.tri()];
                nl += sd == kLeftOnly;
                nr += sd == kRightOnly;
            }
            EventList& l = left.axis[k];
            EventList& r = right.axis[k];
            l.resize(nl + new_left[k].size());
            r.resize(nr + new_right[k].size());
            size_t il = 0, ir = 0;
            for (const Event& e : in) {
                const uint8_t sd = side[e.tri()];
                if (sd == kLeftOnly) l[il++] = e;
                else if (sd == kRightOnly) r[ir++] = e;
            }
            EventList().swap(ev.axis[k]);  // free the parent's list early
            merge_tail(l, nl, new_left[k]);
            merge_tail(r, nr, new_right[k]);
        };
        if (threads_ > 1 && ev.count > kParallelAxes) {
            // Big nodes near the root: the three axes split in parallel.
            auto a1 = std::async(std::launch::async, split_axis, 1);
            auto a2 = std::async(std::launch::async, split_axis, 2);
            split_axis(0);
            a1.get();
            a2.get();
        } else {
            for (int k = 0; k < 3; ++k) split_axis(k);
        }
    }

    // `out` holds `n` sorted events followed by room for `extra`; merges the
    // sorted `extra` in from the back, in place.
    static void merge_tail(EventList& out, size_t n, const EventList& extra) {
        size_t i = n, j = extra.size(), w = n + extra.size();
        while (j > 0) {
            if (i > 0 && extra[j - 1] < out[i - 1]) out[--w] = out[--i];
            else out[--w] = extra[--j];
        }
    }

    std::unique_ptr<BuildNode> make_leaf(const NodeEvents& ev, const Box& box, int depth,
                                         TaskCredit& credit) const {
        Charge(credit, leaf_bytes(opt_, ev.count), depth, "a leaf").keep();
        auto node = std::make_unique<BuildNode>();
        node->area = box.area();
        node->refs.reserve(ev.count);
        for (const Event& e : ev.axis[0])
            if (e.type() != kEnd) node->refs.push_back(e.tri());
        std::sort(node->refs.begin(), node->refs.end());
        if (opt_.leaf_boxes == LeafBoxes::Clipped) {
            // The events hold each triangle's bounds clipped to this cell
            // (padded outwards by the clipper): gather them per reference.
            node->ref_boxes.assign(node->refs.size(), Box());
            for (int k = 0; k < 3; ++k) {
                for (const Event& e : ev.axis[k]) {
                    const size_t i = size_t(std::lower_bound(node->refs.begin(), node->refs.end(),
                                                             e.tri()) - node->refs.begin());
                    Box& b = node->ref_boxes[i];
                    if (e.type() != kEnd) b.lo[k] = e.pos;
                    if (e.type() != kStart) b.hi[k] = e.pos;
                }
            }
        }
        report_leaf(progress_, depth);
        return node;
    }

    std::unique_ptr<BuildNode> build_node(NodeEvents ev, const Box& box, int depth, double budget,
                                          std::vector<uint8_t>& side, TaskCredit& credit) {
        if (progress_) progress_->check();
        memory_.check();
        const float leaf_cost = cost_.leaf(ev.count);
        if (int(ev.count) <= opt_.leaf_size || depth >= opt_.max_depth)
            return make_leaf(ev, box, depth, credit);
        const Split s = find_split(ev, box);
        if (s.axis < 0 || !(s.cost < leaf_cost)) return make_leaf(ev, box, depth, credit);
        const double refs = double(s.n_left) + double(s.n_right);
        if (refs > budget) return make_leaf(ev, box, depth, credit);

        // Charged before anything is allocated: the children's lists (they
        // go with them), the straddling triangles' new events (freed after
        // the split) and this node (kept).
        const uint64_t children = uint64_t(s.n_left) + s.n_right;
        const uint64_t straddling = children > ev.count ? children - ev.count : 0;
        Charge work(credit,
                    kEventBytesPerRef * children + kStraddleBytes * straddling + kBuildNodeBytes,
                    depth, "the children's event lists");
        NodeEvents left, right;
        left.charge = work.take(kEventBytesPerRef * s.n_left);
        right.charge = work.take(kEventBytesPerRef * s.n_right);
        work.take(kBuildNodeBytes).keep();

        Box lbox = box, rbox = box;
        lbox.hi[s.axis] = s.pos;
        rbox.lo[s.axis] = s.pos;
        classify(ev, s, side);
        split_events(ev, s, lbox, rbox, side, left, right);
        // split_events freed the node's own lists: one release for both.
        work.absorb(std::move(ev.charge));
        work.reset();

        double lbudget, rbudget;
        split_budget(budget, s.n_left, s.n_right, lbudget, rbudget);

        auto node = std::make_unique<BuildNode>();
        node->kind = kd_kind(s.axis);
        node->split = s.pos;
        node->area = box.area();
        if (depth < spawn_depth_ && ev.count > 4096) {
            auto right_task = std::async(std::launch::async, [&, r = std::move(right)]() mutable {
                return build(std::move(r), rbox, depth + 1, rbudget);
            });
            node->child[0] = build_node(std::move(left), lbox, depth + 1, lbudget, side, credit);
            node->child[1] = right_task.get();
        } else {
            node->child[0] = build_node(std::move(left), lbox, depth + 1, lbudget, side, credit);
            node->child[1] = build_node(std::move(right), rbox, depth + 1, rbudget, side, credit);
        }
        return node;
    }
};

}  // namespace

Tree build_kd_tree(std::vector<Triangle> triangles, const BuildOptions& options,
                   Progress* progress) {
    return run_builder(std::move(triangles), options, [&](Tree& tree, const Prepared& prep,
                                                          MemoryBudget& memory) {
        TaskCredit credit(memory);
        NodeEvents root;
        root.count = uint32_t(prep.live.size());
        root.charge = Charge(credit, kEventBytesPerRef * prep.live.size(), 0, "the event lists");
        const int threads = resolve_threads(options.threads);
        // The three axes' event lists are independent: fill and sort them in parallel.
        parallel_for(3, 1, threads, [&](size_t k0, size_t k1) {
            for (size_t k = k0; k < k1; ++k) {
                EventList& e = root.axis[k];
                e.reserve(2 * prep.live.size());
                for (uint32_t i : prep.live) add_axis_events(tree.triangles[i].bounds(), i, int(k), e);
                std::sort(e.begin(), e.end());
            }
        });
        KdBuilder builder(tree.triangles, tree.options, progress, threads, memory);
        return builder.build(std::move(root), tree.bounds, 0, prep.ref_budget);
    });
}

}  // namespace bsp
