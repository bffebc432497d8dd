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

// A build task's working memory, reused from node to node so that splitting
// a node allocates only the children's own lists.
struct TaskScratch {
    std::vector<uint8_t> side;            // per triangle: its Side at the current split
    std::vector<uint32_t> straddling;     // the triangles the current plane cuts
    EventList new_left[3], new_right[3];  // their clipped events, per axis
    EventList part[3];                    // per axis: an event list split in two
    Charge part_charge;                   // the part lists' bytes in the memory budget

    // Room for splitting a list of n events along axis k. The parts grow to
    // the task's largest (first) node and stay: charged once, as they grow.
    void reserve_part(int k, size_t n, TaskCredit& credit, int depth) {
        if (part[k].size() >= n) return;
        part_charge.absorb(Charge(credit, (n - part[k].size()) * sizeof(Event), depth,
                                  "a build task's event split lists"));
        part[k].resize(n);
    }
};

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
        TaskScratch scratch;
        scratch.side.resize(tris_.size());
        return build_node(std::move(ev), box, depth, budget, scratch, credit);
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

    // Marks every triangle of the node with the side(s) of `s` it lies on,
    // and lists the triangles the plane cuts (in the order of their starts
    // along the split axis). Every triangle starts as "both", set from the
    // x events, before the split axis's events narrow it down: a start
    // right of the plane, an end left of it, or a planar event. The reset
    // pass cannot be folded into the second: a rounded, clipped box can be
    // inverted (its end before its start), and then the later event wins.
    void classify(const NodeEvents& ev, const Split& s, TaskScratch& scratch) const {
        std::vector<uint8_t>& side = scratch.side;
        for (const Event& e : ev.axis[0])
            if (e.type() != kEnd) side[e.tri()] = kBoth;
        std::vector<uint32_t>& straddling = scratch.straddling;
        straddling.clear();
        for (const Event& e : ev.axis[s.axis]) {
            const uint32_t t = e.tri();
            if (e.type() == kEnd) {
                if (e.pos <= s.pos) side[t] = kLeftOnly;
            } else if (e.type() == kStart) {
                if (e.pos >= s.pos) side[t] = kRightOnly;
                else straddling.push_back(t);  // unless its end turns out left
            } else {
                const bool left = e.pos < s.pos || (e.pos == s.pos && s.planar_left);
                side[t] = left ? kLeftOnly : kRightOnly;
            }
        }
        straddling.erase(std::remove_if(straddling.begin(), straddling.end(),
                                        [&](uint32_t t) { return side[t] != kBoth; }),
                         straddling.end());
    }

    // The clipped events of the straddling triangles on either side, sorted.
    void clip_straddling(const Split& s, const Box& lbox, const Box& rbox,
                         TaskScratch& scratch) const {
        for (int k = 0; k < 3; ++k) {
            scratch.new_left[k].clear();
            scratch.new_right[k].clear();
        }
        Box parent = lbox;
        parent.hi[s.axis] = rbox.hi[s.axis];
        for (uint32_t t : scratch.straddling) {
            Box lb, rb;
            split_clipped_bounds(tris_[t], parent, s.axis, s.pos, lb, rb);
            // The plane cuts the triangle inside the cell, so both halves are
            // non-empty; rounding can still empty one, and then the whole
            // triangle box (conservative) stands in.
            if (lb.empty()) lb = tris_[t].bounds().intersect(lbox);
            if (rb.empty()) rb = tris_[t].bounds().intersect(rbox);
            add_events(lb, t, scratch.new_left);
            add_events(rb, t, scratch.new_right);
        }
    }

    // Splits the node's sorted events along axis k into the children's
    // sorted events: one pass sends each event to its side (left ones to the
    // front of the scratch list, right ones to its back, so no second pass
    // is needed to count them), then each side is merged with the straddling
    // triangles' new events into a list of exactly its size.
    void split_axis(NodeEvents& ev, int k, TaskScratch& scratch, NodeEvents& left,
                    NodeEvents& right) const {
        EventList& new_left = scratch.new_left[k];
        EventList& new_right = scratch.new_right[k];
        std::sort(new_left.begin(), new_left.end());
        std::sort(new_right.begin(), new_right.end());
        const EventList& in = ev.axis[k];
        EventList& part = scratch.part[k];
        const uint8_t* side = scratch.side.data();
        Event* front = part.data();
        Event* back = part.data() + in.size();  // right events, written downwards
        for (const Event& e : in) {
            // Branch-free: both slots are written, one pointer moves. The
            // slot below `back` is free (front < back while events remain),
            // so a write there that does not count is harmless.
            const uint8_t sd = side[e.tri()];
            *front = e;
            back[-1] = e;
            front += sd == kLeftOnly;
            back -= sd == kRightOnly;
        }
        // [back, end) holds the right events in reverse order.
        const size_t nl = size_t(front - part.data());
        const Event* rbegin = back;
        const Event* rend = part.data() + in.size();
        EventList().swap(ev.axis[k]);  // free the parent's list early
        merge_into(left.axis[k], part.data(), part.data() + nl, new_left, false);
        merge_into(right.axis[k], rbegin, rend, new_right, true);
    }

    // out = the sorted merge of [b, e) (reversed if `reversed`) and `extra`;
    // an extra event goes after an equal one of the node's own.
    static void merge_into(EventList& out, const Event* b, const Event* e, const EventList& extra,
                           bool reversed) {
        out.reserve(size_t(e - b) + extra.size());
        size_t j = 0;
        auto add = [&](const Event& own) {
            while (j < extra.size() && extra[j] < own) out.push_back(extra[j++]);
            out.push_back(own);
        };
        if (reversed) {
            while (e != b) add(*--e);
        } else {
            for (; b != e; ++b) add(*b);
        }
        out.insert(out.end(), extra.begin() + j, extra.end());
    }

    void split_events(NodeEvents& ev, const Split& s, const Box& lbox, const Box& rbox,
                      TaskScratch& scratch, TaskCredit& credit, int depth, NodeEvents& left,
                      NodeEvents& right) const {
        clip_straddling(s, lbox, rbox, scratch);
        for (int k = 0; k < 3; ++k) scratch.reserve_part(k, ev.axis[k].size(), credit, depth);
        left.count = s.n_left;
        right.count = s.n_right;
        if (threads_ > 1 && ev.count > kParallelAxes) {
            // Big nodes near the root: the three axes split in parallel.
            auto a1 = std::async(std::launch::async, [&] { split_axis(ev, 1, scratch, left, right); });
            auto a2 = std::async(std::launch::async, [&] { split_axis(ev, 2, scratch, left, right); });
            split_axis(ev, 0, scratch, left, right);
            a1.get();
            a2.get();
        } else {
            for (int k = 0; k < 3; ++k) split_axis(ev, k, scratch, left, right);
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
                                          TaskScratch& scratch, TaskCredit& credit) {
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
        classify(ev, s, scratch);
        split_events(ev, s, lbox, rbox, scratch, credit, depth, left, right);
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
            node->child[0] = build_node(std::move(left), lbox, depth + 1, lbudget, scratch, credit);
            node->child[1] = right_task.get();
        } else {
            node->child[0] = build_node(std::move(left), lbox, depth + 1, lbudget, scratch, credit);
            node->child[1] = build_node(std::move(right), rbox, depth + 1, rbudget, scratch, credit);
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
