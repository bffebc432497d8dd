// The kd builder's binned SAH (build_quality = "fast"): a node of many
// references chooses among `bins - 1` evenly spaced planes per axis instead
// of sweeping every event. The references are counted into bins by their
// (clipped) bounds, so a big node needs no sorted event lists at all: one
// pass over its references, then a prefix sum per axis.
//
// A reference is counted into the bin its box starts in and the bin it
// ends in, by one multiplication per bound; a flat one (lo == hi along the
// axis) is counted as starting and ending in its bin. The counts of a plane
// are then those of the boxes rounded to bin boundaries: close enough to
// choose a plane, while the partition of the references (ref_side) decides
// each side by the true bounds, so a tree never misses a triangle.
#pragma once
#include <algorithm>
#include <cstdint>
#include <vector>

#include "builders/cost_model.hpp"
#include "geometry.hpp"

namespace bsp {

// A reference of a binned node: a triangle and its bounds clipped to the
// node's cell (perfect splits, as the exact builder's events hold them).
struct KdRef {
    Box box;
    uint32_t tri;
};

// The side of the plane x[axis] = pos a reference lies on, by its true
// bounds: the partition of a binned node's references (the bins' counts
// estimate it).
enum class RefSide { Left, Right, Both };
inline RefSide ref_side(const Box& b, int axis, float pos) {
    const float lo = b.lo[axis], hi = b.hi[axis];
    if (lo == hi) return lo <= pos ? RefSide::Left : RefSide::Right;  // flat: in the plane, left
    if (hi <= pos) return RefSide::Left;
    if (lo >= pos) return RefSide::Right;
    return RefSide::Both;
}

struct BinnedSplit {
    int axis = -1;
    float pos = 0;
    float cost = kInf;
    uint32_t n_left = 0, n_right = 0;  // the bins' estimate of the sides
};

// The bins of one node: per axis the planes lo + i (hi - lo) / bins for
// i = 1 .. bins - 1, and how many boxes start and end between them.
class KdBins {
public:
    KdBins() = default;
    KdBins(const Box& box, int bins) { reset(box, bins); }

    // Empty bins over `box`; a task's bins are reset from node to node, so
    // that their arrays are allocated once.
    void reset(const Box& box, int bins) {
        box_ = box;
        bins_ = bins;
        for (int k = 0; k < 3; ++k) {
            Axis& a = axis_[k];
            const float extent = box.hi[k] - box.lo[k];
            a.usable = extent > 0.0f;
            a.lo = box.lo[k];
            a.inv_width = a.usable ? float(bins) / extent : 0.0f;
            a.last = float(bins - 1);
            const float width = extent / float(bins);
            a.planes.resize(size_t(bins));
            for (int i = 0; i < bins; ++i) a.planes[i] = box.lo[k] + float(i) * width;
            a.starts.assign(size_t(bins), 0);
            a.ends.assign(size_t(bins), 0);
        }
    }

    // Counts one reference into the bins of the three axes.
    void add(const Box& b) {
        for (int k = 0; k < 3; ++k) {
            Axis& a = axis_[k];
            ++a.starts[bin_of(a, b.lo[k])];
            ++a.ends[bin_of(a, b.hi[k])];
        }
    }

    // Adds another node part's counts (the same node, binned in chunks).
    void merge(const KdBins& o) {
        for (int k = 0; k < 3; ++k)
            for (int i = 0; i < bins_; ++i) {
                axis_[k].starts[i] += o.axis_[k].starts[i];
                axis_[k].ends[i] += o.axis_[k].ends[i];
            }
    }

    // The cheapest binned plane under the cost model, `count` references in
    // the node: left of plane i the boxes starting in bins below i, right of
    // it those ending in bin i or above. Ties go to the lower axis, then the
    // lower plane (strictly cheaper wins), as in the exact sweep.
    BinnedSplit best(const CostModel& cost, uint32_t count) const {
        BinnedSplit best;
        const float parent_area = box_.area();
        if (!(parent_area > 0.0f)) return best;
        const float inv_area = 1.0f / parent_area;
        const Vec3 d = box_.hi - box_.lo;
        for (int k = 0; k < 3; ++k) {
            const Axis& a = axis_[k];
            if (!a.usable) continue;
            const int u = (k + 1) % 3, v = (k + 2) % 3;
            const float cap = d[u] * d[v], rim = d[u] + d[v];
            uint32_t left = 0, right = count;
            for (int i = 1; i < bins_; ++i) {
                left += a.starts[i - 1];
                right -= a.ends[i - 1];
                const float p = a.planes[i];
                if (!(p > box_.lo[k] && p < box_.hi[k]) || p == a.planes[i - 1]) continue;
                // The same areas the exact sweep prices a plane with.
                const float pl = 2.0f * (cap + (p - box_.lo[k]) * rim) * inv_area;
                const float pr = 2.0f * (cap + (box_.hi[k] - p) * rim) * inv_area;
                const float c = cost.split(cost.kd_step(), pl, left, pr, right);
                if (c < best.cost) best = {k, p, c, left, right};
            }
        }
        return best;
    }

private:
    struct Axis {
        bool usable = false;  // a flat cell has no plane inside along this axis
        float lo = 0, inv_width = 0;
        float last = 0;  // bins - 1, as a float
        std::vector<float> planes;  // planes[i], i >= 1; planes[0] is the cell's face
        std::vector<uint32_t> starts, ends;
    };

    // The bin of position x: [planes[i], planes[i + 1]) is bin i (a flat
    // axis has one bin).
    int bin_of(const Axis& a, float x) const {
        const float t = (x - a.lo) * a.inv_width;
        // Clamped as a float first: a position beyond the cell stays in range.
        if (!(t > 0.0f)) return 0;
        return t < a.last ? int(t) : bins_ - 1;
    }

    Box box_;
    int bins_ = 0;
    Axis axis_[3];
};

}  // namespace bsp
