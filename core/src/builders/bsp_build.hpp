// The one BSP_SWEEP builder: at every node it takes directions from the
// strategy in the options, sweeps the SAH along each, and keeps the cheapest
// plane. RBSP, BSP_random(+), BSP_wn(+), BSP_cn(+), BSP_IZE and their ^Kd
// variants are this builder with different options.
#pragma once
#include <vector>

#include "progress.hpp"
#include "tree.hpp"

namespace bsp {

// A BuildFunction (builders/builder.hpp): a BSP tree over `triangles`.
Tree build_bsp_tree(std::vector<Triangle> triangles, const BuildOptions& options,
                    Progress* progress = nullptr);

}  // namespace bsp
