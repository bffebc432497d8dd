// SAH kd-tree construction in O(N log N) (Wald & Havran 2006).
#pragma once
#include <vector>

#include "kd_tree.hpp"
#include "progress.hpp"

namespace bsp {

// Builds a kd-tree over `triangles` (moved into the tree). Zero-area
// triangles keep their index but are left out of the tree, so they are never
// hit. Throws Cancelled when `progress` is cancelled, std::bad_alloc when the
// tree would exceed options.memory_limit_mb.
KdTree build_kd_tree(std::vector<Triangle> triangles, const BuildOptions& options,
                     Progress* progress = nullptr);

// The SAH cost of a finished tree, relative to a ray hitting the root box.
double sah_cost(const KdTree& tree);

}  // namespace bsp
