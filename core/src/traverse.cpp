// Batches of rays through a tree: checks the arguments, hands chunks of rays
// to threads and each chunk to the kernel of the selected instruction set
// (kernels/, cpu_dispatch.cpp).
#include "traverse.hpp"

#include <stdexcept>

#include "cpu_dispatch.hpp"
#include "parallel.hpp"

namespace bsp {

void intersect(const Tree& tree, const RayBatch& rays, HitBatch& hits, int threads, bool cull,
               Progress* progress) {
    const int given = (hits.steps != nullptr) + (hits.general_steps != nullptr) +
                      (hits.tests != nullptr) + (hits.culled != nullptr);
    if (given != 0 && given != 4)
        throw std::invalid_argument("intersect: give all four counter arrays or none");
    // One instantiation per box kind keeps the culling check out of the loop
    // when off, one per counting policy keeps the counters out of the
    // hits-only path.
    const LeafBoxes boxes = cull ? tree.options.leaf_boxes : LeafBoxes::None;
    const TraceRange trace = selected_kernels().single_ray[given == 4][int(boxes)];
    const TreeView view = make_tree_view(tree);
    const HitBatch& out = hits;
    constexpr size_t kChunk = 1024;
    const uint64_t units_per_ray = rays.count ? Progress::kScale / rays.count : 0;
    parallel_for(rays.count, kChunk, resolve_threads(threads), [&](size_t begin, size_t end) {
        if (progress) progress->check();
        trace(view, rays, out, begin, end);
        if (progress) progress->add(units_per_ray * (end - begin));
    });
}

}  // namespace bsp
