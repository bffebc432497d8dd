// SAH kd-tree construction in O(N log N) (Wald & Havran 2006).
#pragma once
#include <vector>

#include "progress.hpp"
#include "tree.hpp"

namespace bsp {

// A BuildFunction (builders/builder.hpp): a kd-tree over `triangles`.
Tree build_kd_tree(std::vector<Triangle> triangles, const BuildOptions& options,
                   Progress* progress = nullptr);

}  // namespace bsp
