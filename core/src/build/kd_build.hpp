// SAH kd-tree construction in O(N log N) (Wald & Havran 2006).
#pragma once
#include <vector>

#include "tree.hpp"
#include "progress.hpp"

namespace bsp {

// Builds a kd-tree over `triangles` (moved into the tree). Zero-area
// triangles keep their index but are left out of the tree, so they are never
// hit. Throws Cancelled when `progress` is cancelled, MemoryLimitExceeded (a
// std::bad_alloc) as soon as the build would exceed options.memory_limit_mb.
Tree build_kd_tree(std::vector<Triangle> triangles, const BuildOptions& options,
                   Progress* progress = nullptr);

}  // namespace bsp
