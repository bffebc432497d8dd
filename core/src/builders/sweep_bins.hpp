// The fast build quality's candidates along one direction of a big node
// (BuildQuality::Fast, nodes of at least fast_min_refs references): instead
// of sorting every reference's projection and pricing every distinct one,
// the cell's extent along the direction is cut into `bins` equal bins and
// only the bins' inner boundaries are candidate planes. Each reference is
// counted once into the bin its extent starts in and the bin it ends in, so
// a node costs O(n + bins) per direction instead of O(n log n) plus the
// areas at up to 2n candidates.
//
// The counts are exact for every boundary: a reference's bin is found by
// comparing its float extent with the boundaries' float positions (not just
// by scaling, which rounds), and a reference is counted on a boundary's
// sides with split_refs' rules for a plane with planar references on the
// left: below when its extent starts below the plane (lying in the plane
// counts as below), above when it ends above it. So the counts the cost model
// prices are the children's true sizes, as in the exact sweep.
#pragma once
#include <algorithm>
#include <cstdint>
#include <vector>

namespace bsp {

class SweepBins {
public:
    // Bins between lo and hi (the cell's extent along the direction): the
    // boundaries are lo + (hi - lo) k / bins for k = 1 .. bins - 1, rounded
    // to float once (the candidate planes' positions). Counts start at zero.
    void reset(double lo, double hi, int bins) {
        const int m = std::max(bins, 2) - 1;  // inner boundaries
        bounds_.resize(size_t(m));
        for (int k = 0; k < m; ++k) bounds_[size_t(k)] = float(lo + (hi - lo) * double(k + 1) / double(m + 1));
        lo_ = lo;
        scale_ = hi > lo ? double(m + 1) / (hi - lo) : 0.0;
        starts_.assign(size_t(m) + 1, 0);
        ends_.assign(size_t(m) + 1, 0);
    }

    // Counts a reference whose extent along the direction is [lo, hi]
    // (lying in a plane of the family when lo == hi).
    void add(float lo, float hi) {
        if (lo == hi) {
            const size_t p = count_below(lo);  // in boundary k's plane or below it: left
            ++starts_[p];
            ++ends_[p];
        } else {
            ++starts_[count_at_or_below(lo)];
            ++ends_[count_below(hi)];
        }
    }

    // Adds another set of counts over the same boundaries (a thread's share).
    void merge(const SweepBins& other) {
        for (size_t i = 0; i < starts_.size(); ++i) {
            starts_[i] += other.starts_[i];
            ends_[i] += other.ends_[i];
        }
    }

    size_t boundaries() const { return bounds_.size(); }
    float position(size_t k) const { return bounds_[k]; }

    // Walks the boundaries bottom to top: visit(position, below, above) with
    // the references on each side of the plane (crossing ones on both).
    template <class Visit>
    void for_each_boundary(uint32_t total, Visit&& visit) const {
        uint32_t below = 0, above = total;
        for (size_t k = 0; k < bounds_.size(); ++k) {
            below += starts_[k];  // extents starting below boundary k
            above -= ends_[k];    // extents ending at or below it
            visit(bounds_[k], below, above);
        }
    }

private:
    // The number of boundaries strictly below x / at or below x: a guess by
    // scaling, corrected against the float boundaries themselves.
    size_t guess(float x) const {
        const double g = (double(x) - lo_) * scale_;
        if (!(g > 0)) return 0;
        return std::min(size_t(g), bounds_.size());
    }
    size_t count_below(float x) const {
        size_t i = guess(x);
        while (i > 0 && bounds_[i - 1] >= x) --i;
        while (i < bounds_.size() && bounds_[i] < x) ++i;
        return i;
    }
    size_t count_at_or_below(float x) const {
        size_t i = guess(x);
        while (i > 0 && bounds_[i - 1] > x) --i;
        while (i < bounds_.size() && bounds_[i] <= x) ++i;
        return i;
    }

    std::vector<float> bounds_;
    std::vector<uint32_t> starts_, ends_;  // per bin: extents starting / ending in it
    double lo_ = 0, scale_ = 0;
};

}  // namespace bsp
