// The kd builder of Wald & Havran (2006): the 2N extents of the triangles
// along each axis are sorted once at the root; each node sweeps its sorted
// events to find the cheapest SAH plane, then splits its event lists into the
// children's lists without re-sorting. Only triangles that straddle the plane
// get new events: they are clipped to each child box ("perfect splits"), and
// those few new events are sorted and merged in.
//
// build_quality = "fast" (kd_bins.hpp): the nodes of at least fast_min_refs
// references are split at binned planes and hold their references as an
// array of clipped boxes, partitioned from node to node; the root's sorted
// lists are never made. A node below that size sorts its own references'
// events and continues with the exact sweep.
#include "builders/kd_build.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <functional>
#include <future>
#include <memory>

#include "builders/build_tree.hpp"
#include "builders/clip.hpp"
#include "builders/cost_model.hpp"
#include "builders/kd_bins.hpp"
#include "builders/kd_events.hpp"
#include "parallel.hpp"

namespace bsp {
namespace {

using EventList = std::vector<Event>;

struct NodeEvents {
    EventSpan axis[3];   // in the task's EventStack
    uint32_t count = 0;  // triangles in the node
};

// Two events per axis per triangle at most (a planar one has one).
constexpr uint64_t kEventBytesPerRef = 6 * sizeof(Event);
// A triangle straddling a split while the children's lists are made: its
// index and its clipped events on both sides, before they are merged in.
constexpr uint64_t kStraddleBytes = sizeof(uint32_t) + 2 * kEventBytesPerRef;
// A build task's stack of event lists grows in blocks of (at least) this
// many times the events of the task's root: a depth-first build needs
// about twice its root's lists (the right children waiting along the path).
constexpr double kStackBlockShare = 0.5;
// Events of a reference on all three axes, at most.
constexpr size_t kEventsPerRef = 6;
// Fast builds: a binned node's event lists shorter than this are sorted by
// std::sort, longer ones by the radix sort (whose 2048 counters would cost
// more than the events themselves in a small list).
constexpr size_t kRadixMinEvents = 1024;

// A binned node's references and their charge to the memory budget.
struct RefArray {
    std::vector<KdRef> refs;
    Charge charge;
};

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

// kCut: a straddling triangle whose box a fast build cuts at the plane
// (straddling_events): along the other two axes its events go to both
// sides, which the side bits say as they are; along the split axis its
// start goes left and its end right.
enum Side : uint8_t { kBoth = 0, kLeftOnly = 1, kRightOnly = 2, kCut = 3 };

// A build task's working memory, reused from node to node.
struct TaskScratch {
    // Per triangle: its Side at the current split, tagged with the split's
    // pass number, so that a mark left by an earlier node is told apart
    // from one made in this pass without clearing the marks at every node.
    std::vector<uint16_t> marks;
    uint16_t pass = 0;
    std::vector<uint32_t> straddling;     // the triangles the current plane cuts
    EventList new_left[3], new_right[3];  // their clipped events, per axis
    EventStack stack;                     // the nodes' event lists
    EventList sort_in, sort_tmp;          // fast builds: a binned node's events being sorted
    NodeArena::Local& nodes;              // the task's build nodes and leaf lists

    TaskScratch(size_t block_events, NodeArena::Local& task_nodes)
        : stack(block_events), nodes(task_nodes) {}

    // The tag of a new pass (above the two Side bits). After 2^14 passes
    // the tags start over, with every mark cleared.
    uint16_t next_pass() {
        if (++pass == (1u << 14)) {
            std::fill(marks.begin(), marks.end(), uint16_t(0));
            pass = 1;
        }
        return uint16_t(pass << 2);
    }
};

class KdBuilder : BuilderBase {
public:
    using BuilderBase::BuilderBase;

    // A build task: the root, or a subtree on a thread of its own. Its
    // lists are copied into the task's own stack first; then `copied` runs
    // (the root's frees the lists it was given).
    BuildNode* build(const NodeEvents& from, const Box& box, int depth, double budget,
                     const std::function<void()>& copied = {}) {
        TaskCredit credit(memory_);
        const Charge side_charge(credit, tris_.size() * sizeof(uint16_t), depth,
                                 "a build task's triangle marks");
        const size_t events = from.axis[0].size + from.axis[1].size + from.axis[2].size;
        NodeArena::Local nodes(arena_);
        TaskScratch scratch(size_t(double(events) * kStackBlockShare), nodes);
        scratch.marks.resize(tris_.size());
        // The first block holds the lists and, for a depth-first build, about
        // as much again for the right children waiting along the path.
        Event* room = scratch.stack.push(2 * events, credit, depth);
        scratch.stack.shrink_last(room, events);
        NodeEvents ev;
        ev.count = from.count;
        for (int k = 0; k < 3; ++k) {
            ev.axis[k] = {room, from.axis[k].size};
            room = std::copy(from.axis[k].begin(), from.axis[k].end(), room);
        }
        if (copied) copied();
        return build_node(ev, box, depth, budget, scratch, credit);
    }

    // A fast build's task (the root, or a binned subtree on a thread of its
    // own): its references' charge moves to the task's credit first.
    BuildNode* build_binned(RefArray refs, const Box& box, int depth, double budget) {
        TaskCredit credit(memory_);
        refs.charge.move_to(credit);
        BinnedTask task{credit, nullptr, Charge(), KdBins(), NodeArena::Local(arena_)};
        return build_binned_node(std::move(refs), box, depth, budget, task);
    }

private:
    // A binned task's exact part: its scratch (the triangle marks, the event
    // stack) made when the first of its nodes falls below fast_min_refs.
    struct BinnedTask {
        TaskCredit& credit;
        std::unique_ptr<TaskScratch> scratch;
        Charge marks;
        KdBins bins;  // the binned nodes', reset from node to node
        NodeArena::Local nodes;  // every node of the task, binned or exact (the scratch's too)
    };

    // Binned nodes of more references than this bin and partition them in
    // chunks of this many on several threads (near the root, while the
    // subtrees do not yet keep every thread busy). The chunks do not depend
    // on the thread count, nor does the order of the references they give.
    static constexpr size_t kRefChunk = 1u << 15;

    bool parallel_node(int depth, size_t refs) const {
        return threads_ > 1 && refs > 2 * kRefChunk && (1 << depth) < threads_;
    }

    // The cheapest binned plane of a node, or none (axis -1).
    BinnedSplit find_binned_split(const std::vector<KdRef>& refs, const Box& box, int depth,
                                  KdBins& total) const {
        const int bins = opt_.fast_bins;
        total.reset(box, bins);
        if (parallel_node(depth, refs.size())) {
            const size_t chunks = (refs.size() + kRefChunk - 1) / kRefChunk;
            std::vector<KdBins> part(chunks, KdBins(box, bins));
            parallel_for(refs.size(), kRefChunk, threads_, [&](size_t b, size_t e) {
                KdBins& bins_of = part[b / kRefChunk];
                for (size_t i = b; i < e; ++i) bins_of.add(refs[i].box);
            });
            for (const KdBins& p : part) total.merge(p);
        } else {
            for (const KdRef& r : refs) total.add(r.box);
        }
        return total.best(cost_, uint32_t(refs.size()));
    }

    // Sorts one chunk of a binned node's references to the sides of the
    // split, in order; a reference the plane cuts is clipped into both
    // ("perfect splits", as clip_straddling does for the exact build).
    void partition_chunk(const KdRef* begin, const KdRef* end, const Box& box, int axis, float pos,
                         const Box& lbox, const Box& rbox, std::vector<KdRef>& left,
                         std::vector<KdRef>& right) const {
        for (const KdRef* r = begin; r != end; ++r) {
            switch (ref_side(r->box, axis, pos)) {
            case RefSide::Left: left.push_back(*r); break;
            case RefSide::Right: right.push_back(*r); break;
            case RefSide::Both: {
                Box lb, rb;
                split_clipped_bounds(tris_[r->tri], box, axis, pos, lb, rb);
                if (lb.empty()) lb = tris_[r->tri].bounds().intersect(lbox);
                if (rb.empty()) rb = tris_[r->tri].bounds().intersect(rbox);
                left.push_back({lb, r->tri});
                right.push_back({rb, r->tri});
            }
            }
        }
    }

    void partition(const std::vector<KdRef>& refs, const Box& box, const BinnedSplit& s,
                   const Box& lbox, const Box& rbox, int depth, std::vector<KdRef>& left,
                   std::vector<KdRef>& right) const {
        left.reserve(s.n_left);
        right.reserve(s.n_right);
        if (!parallel_node(depth, refs.size())) {
            partition_chunk(refs.data(), refs.data() + refs.size(), box, s.axis, s.pos, lbox,
                            rbox, left, right);
            return;
        }
        const size_t chunks = (refs.size() + kRefChunk - 1) / kRefChunk;
        std::vector<std::vector<KdRef>> l(chunks), r(chunks);
        parallel_for(refs.size(), kRefChunk, threads_, [&](size_t b, size_t e) {
            const size_t c = b / kRefChunk;
            partition_chunk(refs.data() + b, refs.data() + e, box, s.axis, s.pos, lbox, rbox,
                            l[c], r[c]);
        });
        for (size_t c = 0; c < chunks; ++c) {
            left.insert(left.end(), l[c].begin(), l[c].end());
            right.insert(right.end(), r[c].begin(), r[c].end());
        }
    }

    // Charges what a partitioned array holds beyond what was charged for it.
    static void top_up(RefArray& a, int depth, TaskCredit& credit) {
        const uint64_t held = sizeof(KdRef) * a.refs.capacity();
        if (held > a.charge.bytes())
            a.charge.absorb(Charge(credit, held - a.charge.bytes(), depth,
                                   "the children's references"));
    }

    BuildNode* build_binned_node(RefArray refs, const Box& box, int depth, double budget,
                                 BinnedTask& task) {
        check_stop();
        const size_t n = refs.refs.size();
        if (n < size_t(opt_.fast_min_refs) || int(n) <= opt_.leaf_size || depth >= opt_.max_depth)
            return build_exact_below(std::move(refs), box, depth, budget, task);
        const BinnedSplit s = find_binned_split(refs.refs, box, depth, task.bins);
        // No binned plane pays, or the budget is spent: the exact sweep
        // decides (a leaf, most likely), as it would have.
        if (s.axis < 0 || !(s.cost < cost_.leaf(n)) ||
            double(s.n_left) + double(s.n_right) > budget)
            return build_exact_below(std::move(refs), box, depth, budget, task);

        Charge(task.credit, kBuildNodeBytes, depth, "a build node").keep();
        Box lbox = box, rbox = box;
        lbox.hi[s.axis] = s.pos;
        rbox.lo[s.axis] = s.pos;
        RefArray left, right;
        left.charge = Charge(task.credit, sizeof(KdRef) * s.n_left, depth, "the children's references");
        right.charge = Charge(task.credit, sizeof(KdRef) * s.n_right, depth, "the children's references");
        partition(refs.refs, box, s, lbox, rbox, depth, left.refs, right.refs);
        refs = RefArray();  // the node's own array is not needed any more
        // The bins' counts round the boxes to the bins: the true sides can
        // hold a few more.
        top_up(left, depth, task.credit);
        top_up(right, depth, task.credit);

        double lbudget, rbudget;
        split_budget(budget, double(left.refs.size()), double(right.refs.size()), lbudget, rbudget);
        BuildNode* node = task.nodes.make<BuildNode>();
        node->kind = kd_kind(s.axis);
        node->split = s.pos == 0.0f ? 0.0f : s.pos;
        node->area = box.area();
        if (spawns(n, std::min(left.refs.size(), right.refs.size()))) {
            auto right_task = spawn([&] {
                return build_binned(std::move(right), rbox, depth + 1, rbudget);
            });
            node->child[0] = build_binned_node(std::move(left), lbox, depth + 1, lbudget, task);
            node->child[1] = right_task.get();
        } else {
            node->child[0] = build_binned_node(std::move(left), lbox, depth + 1, lbudget, task);
            node->child[1] = build_binned_node(std::move(right), rbox, depth + 1, rbudget, task);
        }
        return node;
    }

    // A node below the binned size: its references' clipped boxes become
    // sorted event lists on the task's stack, and the exact sweep builds
    // the subtree from there.
    BuildNode* build_exact_below(RefArray refs, const Box& box, int depth, double budget,
                                 BinnedTask& task) {
        if (!task.scratch) {
            task.marks = Charge(task.credit, tris_.size() * sizeof(uint16_t), depth,
                                "a build task's triangle marks");
            const size_t block = size_t(double(kEventsPerRef * opt_.fast_min_refs) * 2 * kStackBlockShare);
            task.scratch = std::make_unique<TaskScratch>(block, task.nodes);
            task.scratch->marks.resize(tris_.size());
        }
        TaskScratch& scratch = *task.scratch;
        const EventStack::Mark mark = scratch.stack.mark();
        NodeEvents ev;
        ev.count = uint32_t(refs.refs.size());
        for (int k = 0; k < 3; ++k) {
            EventList& e = scratch.sort_in;
            e.clear();
            for (const KdRef& r : refs.refs) add_axis_events(r.box, r.tri, k, e);
            if (e.size() < kRadixMinEvents) std::sort(e.begin(), e.end());
            else radix_sort_events(e, scratch.sort_tmp);
            Event* room = scratch.stack.push(e.size(), task.credit, depth);
            std::copy(e.begin(), e.end(), room);
            ev.axis[k] = {room, e.size()};
        }
        refs = RefArray();
        BuildNode* node = build_node(ev, box, depth, budget, scratch, task.credit);
        scratch.stack.release(mark);
        return node;
    }

    // The cheapest SAH split along axis k, sweeping its sorted events once.
    Split find_split_axis(const NodeEvents& ev, const Box& box, int k) const {
        Split best;
        const Vec3 d = box.hi - box.lo;
        const float parent_area = box.area();
        if (!(parent_area > 0.0f) || !(d[k] > 0.0f)) return best;
        const float inv_area = 1.0f / parent_area;
        const int a = (k + 1) % 3, b = (k + 2) % 3;
        const float cap = d[a] * d[b], rim = d[a] + d[b];
        // Read once: Vec3's operator[] branches on k, and in the loop below
        // those branches were a sixth of the sweep's instructions.
        const float lo = box.lo[k], hi = box.hi[k];
        const EventSpan& e = ev.axis[k];
        // The children's surface areas over the parent's at plane p.
        const auto child_areas = [&](float p, float& pl, float& pr) {
            pl = 2.0f * (cap + (p - lo) * rim) * inv_area;
            pr = 2.0f * (cap + (hi - p) * rim) * inv_area;
        };
        uint32_t nl = 0, nr = ev.count;
        for (size_t i = 0; i < e.size;) {
            const float p = e[i].pos;
            // The events at p, counted by type (ends, planars, starts: the
            // sort put them in that order, so counting needs no order).
            uint32_t by_type[4] = {0, 0, 0, 0};
            do {
                ++by_type[e[i].type()];
            } while (++i < e.size && e[i].pos == p);
            const uint32_t ends = by_type[kEnd], planars = by_type[kPlanar],
                           starts = by_type[kStart];
            nr -= planars + ends;
            const bool inside = p > lo && p < hi;
            if (planars == 0) {
                // Most positions: no planar triangle, so one plane inside
                // the cell and one cost.
                if (inside) {
                    float pl, pr;
                    child_areas(p, pl, pr);
                    const float cost = cost_.split(cost_.kd_step(), pl, nl, pr, nr);
                    if (cost < best.cost) best = {k, p, true, cost, nl, nr};
                }
                nl += starts;
                continue;
            }
            // On the cell's own face a split can still pay: it cuts the
            // triangles lying in that face (walls, floors) off into a flat
            // cell, so rays crossing the rest of the cell never test them.
            const bool at_lo = p == lo, at_hi = p == hi;
            if (inside || at_lo || at_hi) {
                float pl, pr;
                child_areas(p, pl, pr);
                // Planar triangles go left, then right (the first of equal
                // costs stays); at the cell's faces only to the flat side.
                const int last = at_lo ? 1 : 0;
                for (int planar_left = at_hi ? 0 : 1; planar_left >= last; --planar_left) {
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
    // along the split axis), in one pass over the split axis's events: a
    // start right of the plane, an end left of it, or a planar event decide
    // the side, and a triangle none of them decides lies on both. A rounded,
    // clipped box can be inverted (its end before its start); then the
    // later event wins, and a start left of the plane keeps the left mark
    // its end made in this pass.
    void classify(const NodeEvents& ev, const Split& s, TaskScratch& scratch) const {
        uint16_t* marks = scratch.marks.data();
        const uint16_t now = scratch.next_pass();
        std::vector<uint32_t>& straddling = scratch.straddling;
        straddling.clear();
        for (const Event& e : ev.axis[s.axis]) {
            const uint32_t t = e.tri();
            if (e.type() == kEnd) {
                if (e.pos <= s.pos) marks[t] = now | kLeftOnly;
            } else if (e.type() == kStart) {
                if (e.pos >= s.pos) {
                    marks[t] = now | kRightOnly;
                } else if ((marks[t] & ~3u) != now) {
                    marks[t] = now | kBoth;
                    straddling.push_back(t);  // unless its end turns out left
                }
            } else {
                const bool left = e.pos < s.pos || (e.pos == s.pos && s.planar_left);
                marks[t] = now | (left ? kLeftOnly : kRightOnly);
            }
        }
        straddling.erase(std::remove_if(straddling.begin(), straddling.end(),
                                        [&](uint32_t t) { return (marks[t] & 3u) != kBoth; }),
                         straddling.end());
    }

    // A fast build cuts a straddling triangle's box at the plane instead of
    // clipping the triangle where the children hold fewer than
    // fast_clip_min_refs references (tree.hpp, kFastClipMinRefs).
    bool cuts_boxes(const Split& s) const {
        return opt_.build_quality == BuildQuality::Fast &&
               uint64_t(s.n_left) + s.n_right < uint64_t(std::max(opt_.fast_clip_min_refs, 0));
    }

    // The straddling triangles' new events on either side: the bounds of
    // each half of the triangle clipped to the cell, or, where the node cuts
    // boxes, only an end (left) and a start (right) at the plane; their old
    // events stay (split_axis) and bound the halves with the node's box of
    // the triangle. Cutting costs no clip, no sort and no merge along the
    // other two axes; the halves' boxes are looser (docs/build_quality.md).
    void straddling_events(const Split& s, const Box& lbox, const Box& rbox, bool cut_boxes,
                           TaskScratch& scratch) const {
        for (int k = 0; k < 3; ++k) {
            scratch.new_left[k].clear();
            scratch.new_right[k].clear();
        }
        if (cut_boxes) {
            uint16_t* marks = scratch.marks.data();
            for (uint32_t t : scratch.straddling) {
                marks[t] |= kCut;
                scratch.new_left[s.axis].push_back({s.pos, t << 2 | kEnd});
                scratch.new_right[s.axis].push_back({s.pos, t << 2 | kStart});
            }
            return;
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
    // sorted events in one pass (cut_axis: the split's axis where the node
    // cuts boxes, else -1): the left ones move down in place (the left
    // child's list overwrites the node's own, which is never read again),
    // the right ones go to `right_room` on top of the stack. Then each side
    // takes in the straddling triangles' new events by a merge from the back,
    // in place. The left side with its new events never holds more than the
    // node did along this axis (a cut triangle's new events replace as many
    // of its own), except that a rounded, inverted clipped box can add one:
    // then it returns false, the left's own events at the front of the
    // node's list, and move_left finishes it.
    bool split_axis(NodeEvents& ev, int k, int cut_axis, TaskScratch& scratch, Event* right_room,
                    NodeEvents& left, NodeEvents& right, size_t& nl) const {
        EventList& new_left = scratch.new_left[k];
        EventList& new_right = scratch.new_right[k];
        std::sort(new_left.begin(), new_left.end());
        std::sort(new_right.begin(), new_right.end());
        const EventSpan in = ev.axis[k];
        const uint16_t* marks = scratch.marks.data();
        Event* l = in.data;
        Event* r = right_room;
        static_assert(kLeftOnly == 1 && kRightOnly == 2 && kBoth == 0 && kCut == 3);
        static_assert(sizeof(Event) == 8 && offsetof(Event, key) == 4);
        if (k != cut_axis) {
            for (const Event& e : in) {
                // Branch-free: both are written, one pointer moves (both for
                // a cut triangle). The slot at l is the one just read or an
                // earlier one (l never passes the reader), and the one at r
                // is free room. The side's two bits are the steps themselves:
                // compares here became a branch, mispredicted on every axis
                // but the split's. The event moves as one 8-byte word (pos
                // low, key high).
                uint64_t word;
                std::memcpy(&word, &e, sizeof word);
                const uint32_t sd = marks[uint32_t(word >> 34)] & 3u;  // key >> 2
                std::memcpy(static_cast<void*>(l), &word, sizeof word);
                std::memcpy(static_cast<void*>(r), &word, sizeof word);
                l += sd & 1u;
                r += sd >> 1;
            }
        } else {
            // The split axis of a node that cuts boxes: a cut triangle's
            // start goes left and its end right (straddling_events closes
            // each half at the plane). A loop of its own, so that the one
            // above, the hot one of every build, keeps its four steps.
            for (const Event& e : in) {
                uint64_t word;
                std::memcpy(&word, &e, sizeof word);
                const uint32_t sd = marks[uint32_t(word >> 34)] & 3u;
                const uint32_t start = ((word >> 32) & 3u) == kStart;
                const uint32_t whole = sd != kCut;
                std::memcpy(static_cast<void*>(l), &word, sizeof word);
                std::memcpy(static_cast<void*>(r), &word, sizeof word);
                l += (sd & 1u) & (start | whole);
                r += (sd >> 1) & ((start ^ 1u) | whole);
            }
        }
        nl = size_t(l - in.data);
        const size_t nr = size_t(r - right_room);
        right.axis[k] = {right_room, nr + new_right.size()};
        merge_tail(right_room, nr, new_right);
        if (nl + new_left.size() > in.size) return false;
        left.axis[k] = {in.data, nl + new_left.size()};
        merge_tail(in.data, nl, new_left);
        return true;
    }

    // The left list that did not fit in place: moved to the stack, then merged.
    void move_left(const NodeEvents& ev, int k, size_t nl, TaskScratch& scratch,
                   NodeEvents& left, TaskCredit& credit, int depth) const {
        const EventList& new_left = scratch.new_left[k];
        Event* out = scratch.stack.push(nl + new_left.size(), credit, depth);
        std::copy(ev.axis[k].data, ev.axis[k].data + nl, out);
        left.axis[k] = {out, nl + new_left.size()};
        merge_tail(out, nl, new_left);
    }

    // `out` holds `n` sorted events followed by room for `extra`; merges the
    // sorted `extra` in from the back, in place (an extra event goes after
    // an equal one of the node's own).
    static void merge_tail(Event* out, size_t n, const EventList& extra) {
        size_t i = n, j = extra.size(), w = n + extra.size();
        while (j > 0) {
            if (i > 0 && extra[j - 1] < out[i - 1]) out[--w] = out[--i];
            else out[--w] = extra[--j];
        }
    }

    void split_events(NodeEvents& ev, const Split& s, const Box& lbox, const Box& rbox,
                      TaskScratch& scratch, TaskCredit& credit, int depth, NodeEvents& left,
                      NodeEvents& right) const {
        const bool cut_boxes = cuts_boxes(s);
        straddling_events(s, lbox, rbox, cut_boxes, scratch);
        const int cut_axis = cut_boxes ? s.axis : -1;
        left.count = s.n_left;
        right.count = s.n_right;
        // The right side needs at most the node's events plus the new ones.
        auto room = [&](int k) { return ev.axis[k].size + scratch.new_right[k].size(); };
        size_t nl[3];
        bool fits[3];
        if (threads_ > 1 && ev.count > kParallelAxes) {
            // Big nodes near the root: the three axes split in parallel, each
            // into room taken beforehand (the stack is not shared by threads).
            Event* r[3];
            for (int k = 0; k < 3; ++k) r[k] = scratch.stack.push(room(k), credit, depth);
            auto task = [&](int k) { fits[k] = split_axis(ev, k, cut_axis, scratch, r[k], left, right, nl[k]); };
            auto a1 = std::async(std::launch::async, task, 1);
            auto a2 = std::async(std::launch::async, task, 2);
            task(0);
            a1.get();
            a2.get();
            for (int k = 0; k < 3; ++k)
                if (!fits[k]) move_left(ev, k, nl[k], scratch, left, credit, depth);
        } else {
            for (int k = 0; k < 3; ++k) {
                Event* r = scratch.stack.push(room(k), credit, depth);
                fits[k] = split_axis(ev, k, cut_axis, scratch, r, left, right, nl[k]);
                scratch.stack.shrink_last(r, right.axis[k].size);
                if (!fits[k]) move_left(ev, k, nl[k], scratch, left, credit, depth);
            }
        }
    }

    BuildNode* make_leaf(const NodeEvents& ev, const Box& box, int depth, TaskScratch& scratch,
                         TaskCredit& credit) const {
        Charge(credit, leaf_bytes(opt_, ev.count), depth, "a leaf").keep();
        BuildNode* node = scratch.nodes.make<BuildNode>();
        node->area = box.area();
        // One start or planar event per triangle along every axis.
        size_t count = 0;
        for (const Event& e : ev.axis[0]) count += e.type() != kEnd;
        uint32_t* refs = scratch.nodes.array<uint32_t>(count);
        uint32_t* end = refs;
        for (const Event& e : ev.axis[0])
            if (e.type() != kEnd) *end++ = e.tri();
        std::sort(refs, end);
        node->refs = refs;
        node->count = uint32_t(end - refs);
        if (opt_.leaf_boxes == LeafBoxes::Clipped) {
            // The events hold each triangle's bounds clipped to this cell
            // (padded outwards by the clipper): gather them per reference.
            node->ref_boxes = scratch.nodes.array<Box>(node->count);
            std::fill(node->ref_boxes, node->ref_boxes + node->count, Box());
            for (int k = 0; k < 3; ++k) {
                for (const Event& e : ev.axis[k]) {
                    const size_t i = size_t(std::lower_bound(refs, end, e.tri()) - refs);
                    Box& b = node->ref_boxes[i];
                    if (e.type() != kEnd) b.lo[k] = e.pos;
                    if (e.type() != kStart) b.hi[k] = e.pos;
                }
            }
        }
        report_leaf(progress_, depth);
        return node;
    }

    BuildNode* build_node(NodeEvents ev, const Box& box, int depth, double budget,
                          TaskScratch& scratch, TaskCredit& credit) {
        check_stop();
        if (int(ev.count) <= opt_.leaf_size || depth >= opt_.max_depth)
            return make_leaf(ev, box, depth, scratch, credit);
        const Split s = find_split(ev, box);
        if (s.axis < 0 || !(s.cost < cost_.split_limit(ev.count)))
            return make_leaf(ev, box, depth, scratch, credit);
        const double refs = double(s.n_left) + double(s.n_right);
        if (refs > budget) return make_leaf(ev, box, depth, scratch, credit);

        // The straddling triangles' new events (freed after the split) and
        // this node (kept); the children's lists are the stack's.
        const uint64_t children = uint64_t(s.n_left) + s.n_right;
        const uint64_t straddling = children > ev.count ? children - ev.count : 0;
        Charge(credit, kBuildNodeBytes, depth, "a build node").keep();
        Charge work(credit, kStraddleBytes * straddling, depth, "the children's event lists");
        NodeEvents left, right;
        const EventStack::Mark mark = scratch.stack.mark();

        Box lbox = box, rbox = box;
        lbox.hi[s.axis] = s.pos;
        rbox.lo[s.axis] = s.pos;
        classify(ev, s, scratch);
        split_events(ev, s, lbox, rbox, scratch, credit, depth, left, right);
        work.reset();

        double lbudget, rbudget;
        split_budget(budget, s.n_left, s.n_right, lbudget, rbudget);

        BuildNode* node = scratch.nodes.make<BuildNode>();
        node->kind = kd_kind(s.axis);
        // -0 and +0 are the same plane, and the sweep may meet either first
        // among equal events (their order is the sort's): store one of them.
        node->split = s.pos == 0.0f ? 0.0f : s.pos;
        node->area = box.area();
        if (spawns(ev.count, std::min(left.count, right.count))) {
            // The right lists stay put until the task has copied them: the
            // left subtree only writes above them.
            auto right_task = spawn([&] {
                return build(right, rbox, depth + 1, rbudget);
            });
            node->child[0] = build_node(left, lbox, depth + 1, lbudget, scratch, credit);
            node->child[1] = right_task.get();
        } else {
            node->child[0] = build_node(left, lbox, depth + 1, lbudget, scratch, credit);
            node->child[1] = build_node(right, rbox, depth + 1, rbudget, scratch, credit);
        }
        scratch.stack.release(mark);
        return node;
    }
};

// A fast build's root: every live triangle's bounds as a reference.
BuildNode* build_binned_root(Tree& tree, const Prepared& prep, MemoryBudget& memory,
                             NodeArena& arena, TaskCredit& credit, int threads,
                             Progress* progress) {
    const size_t n = prep.live.size();
    RefArray root;
    root.charge = Charge(credit, sizeof(KdRef) * n, 0, "the root's references");
    root.refs.resize(n);
    parallel_for(n, size_t(1) << 16, threads, [&](size_t b, size_t e) {
        for (size_t i = b; i < e; ++i) {
            const uint32_t t = prep.live[i];
            root.refs[i] = {tree.triangles[t].bounds(), t};
        }
    });
    KdBuilder builder(tree.triangles, tree.options, progress, threads, memory, arena);
    return builder.build_binned(std::move(root), tree.bounds, 0, prep.ref_budget);
}

}  // namespace

Tree build_kd_tree(std::vector<Triangle> triangles, const BuildOptions& options,
                   Progress* progress) {
    return run_builder(std::move(triangles), options, [&](Tree& tree, const Prepared& prep,
                                                          MemoryBudget& memory, NodeArena& arena) {
        TaskCredit credit(memory);
        const size_t n = prep.live.size();
        const int threads = resolve_threads(options.threads);
        if (options.build_quality == BuildQuality::Fast && n >= size_t(options.fast_min_refs))
            return build_binned_root(tree, prep, memory, arena, credit, threads, progress);
        // The lists and, while they are sorted, as much again.
        Charge lists(credit, kEventBytesPerRef * n, 0, "the event lists");
        Charge sorting(credit, kEventBytesPerRef * n, 0, "sorting the event lists");
        EventList axis[3], sort_tmp[3];
        // The three axes' event lists are independent: fill and sort them in parallel.
        // Three threads even on two cores: the last axis is then shared
        // rather than left to one core while the other idles.
        parallel_for(3, 1, threads > 1 ? 3 : 1, [&](size_t k0, size_t k1) {
            for (size_t k = k0; k < k1; ++k) {
                EventList& e = axis[k];
                e.reserve(2 * n);
                for (uint32_t i : prep.live) add_axis_events(tree.triangles[i].bounds(), i, int(k), e);
                radix_sort_events(e, sort_tmp[k]);
                EventList().swap(sort_tmp[k]);
            }
        });
        sorting.reset();
        NodeEvents root;
        root.count = uint32_t(n);
        for (int k = 0; k < 3; ++k) root.axis[k] = {axis[k].data(), axis[k].size()};
        KdBuilder builder(tree.triangles, tree.options, progress, threads, memory, arena);
        // The root task copies the lists into its stack; these go at once.
        return builder.build(root, tree.bounds, 0, prep.ref_budget, [&] {
            for (EventList& e : axis) EventList().swap(e);
            lists.reset();
        });
    });
}

}  // namespace bsp
