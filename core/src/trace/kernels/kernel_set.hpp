// The tracing kernels of one instruction set. kernels/trace_kernels.cpp is
// compiled once per level (CMakeLists.txt: BSPLAB_ISA_LEVELS), each time into
// a namespace of its own (bsp::isa_sse2, bsp::isa_avx2, bsp::isa_avx512) with
// that level's compiler flags; cpu_dispatch.cpp picks one at run time.
#pragma once
#include <cstddef>

#include "trace/traverse.hpp"
#include "trace/kernels/tree_view.hpp"

namespace bsp {

// Traces rays [begin, end) of the batch into the hit arrays. The dispatching
// code owns the threads and the progress: the kernels only trace, so that no
// threading code is ever compiled for a level the CPU may lack.
using TraceRange = void (*)(const TreeView& tree, const RayBatch& rays, const HitBatch& hits,
                            size_t begin, size_t end);

struct KernelSet {
    const char* isa;
    // [counting][leaf boxes used for culling: None, Triangle, Clipped]
    TraceRange single_ray[2][3];
    // Hits only, no culling: consecutive rays in packets of packet_width
    // (kernels/packet.hpp), the same hits as single_ray[0][0].
    TraceRange packets;
    int packet_width;
    // Trees of Structure::Bvh, [counting]: the wide walk, BvhWideNode::kWidth
    // = 8 children a node (kernels/bvh_wide_single_ray.hpp). Their packets
    // trace one ray at a time through bvh_single_ray[0].
    TraceRange bvh_single_ray[2];
    // The binary walk (kernels/bvh_single_ray.hpp), hits only: the wide
    // walk's reference in the C++ tests and the layout benchmark's binary
    // figure (BSPLAB_BVH_WALK=binary, traverse.cpp).
    TraceRange bvh_binary_hits;
};

namespace isa_sse2 { const KernelSet& kernel_set(); }
namespace isa_avx2 { const KernelSet& kernel_set(); }
namespace isa_avx512 { const KernelSet& kernel_set(); }

}  // namespace bsp
