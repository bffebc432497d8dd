// The sweep builder's sort of a node's projections along one direction (its
// references' extent starts, ends and planar positions).
//
// Why not std::sort alone: a sweep node sorts three lists per direction, and
// in the nodes of a few hundred to a few thousand references, where an
// interior's walls and floors keep many, those comparisons are about as
// unpredictable as branches get. A radix sort has no data-dependent branch;
// bsp_wn+kd K = 8 built conference in 0.78 of the time and bunny in 0.91
// (docs/performance.md, "The sweep's sorts").
#pragma once
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "radix_sort.hpp"

namespace bsp {

// Lists shorter than this are sorted by std::sort: the radix sort's 1,024
// counters cost more than a short list. 256 measured quicker than 1,024 and
// as quick as 64 (bsp_wn+kd K = 8 on conference and bunny).
constexpr size_t kRadixMinProjections = 256;

// Sorts v ascending (the radix sort's key: float_order_bits, -0 taken as
// +0); tmp is scratch room. Both sorts give the same floats in the same
// order (so the same trees): an ascending sequence of floats without NaN is
// unique but for where -0 and +0 fall among its zeros. The radix sort keeps
// those in the order they came; a projection is -0 only along an axis, from
// a vertex at -0 whose other coordinates are both negative or -0.
inline void sort_projections(std::vector<float>& v, std::vector<float>& tmp) {
    if (v.size() < kRadixMinProjections) {
        std::sort(v.begin(), v.end());
        return;
    }
    tmp.resize(v.size());
    if (radix_sort<8, 4>(v.data(), tmp.data(), v.size(), float_order_bits) != v.data()) v.swap(tmp);
}

}  // namespace bsp
