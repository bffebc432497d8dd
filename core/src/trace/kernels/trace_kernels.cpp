// The tracing kernels of one instruction-set level. CMake compiles this file
// once per level (BSPLAB_ISA_LEVELS in CMakeLists.txt) with that level's
// flags and -DBSPLAB_ISA_NS=isa_<level>; cpu_dispatch.cpp chooses at run time.
//
// Two rules keep a level's instructions from running on a CPU without them:
// everything here has internal linkage (the kernel headers' anonymous
// namespace), and every exported entry is `flatten`, so the shared headers'
// inline functions (the triangle test, the node accessors) are inlined rather
// than emitted as out-of-line copies the linker could pick for another level
// (sanitizer builds keep the rule another way: trace/kernel_inlining.hpp).
// CMake checks the second rule on the object files (cmake/check_kernel_objects.cmake).
// -ffp-contract=off on every level: no fused multiply-add, so each level's
// arithmetic - and so its hits - is bit-identical to the baseline's.
#include "trace/kernel_inlining.hpp"
#include "trace/kernels/bvh_single_ray.hpp"
#include "trace/kernels/bvh_wide_single_ray.hpp"
#include "trace/kernels/kernel_set.hpp"
#include "trace/kernels/packet.hpp"
#include "trace/kernels/single_ray.hpp"

#define BSPLAB_STR2(x) #x
#define BSPLAB_STR(x) BSPLAB_STR2(x)

namespace bsp::BSPLAB_ISA_NS {
namespace {

template <LeafBoxes kBoxes, class Counters>
BSPLAB_KERNEL_FLATTEN void single_ray_entry(const TreeView& view, const RayBatch& rays,
                                            const HitBatch& hits, size_t begin, size_t end) {
    trace_single_rays<kBoxes, Counters>(view, rays, hits, begin, end);
}

BSPLAB_KERNEL_FLATTEN void packet_entry(const TreeView& view, const RayBatch& rays,
                                        const HitBatch& hits, size_t begin, size_t end) {
    trace_packets(view, rays, hits, begin, end);
}

template <class Counters>
BSPLAB_KERNEL_FLATTEN void bvh_entry(const TreeView& view, const RayBatch& rays,
                                     const HitBatch& hits, size_t begin, size_t end) {
    bvh_trace_rays<Counters>(view, rays, hits, begin, end);
}

template <class Counters>
BSPLAB_KERNEL_FLATTEN void bvh_wide_entry(const TreeView& view, const RayBatch& rays,
                                          const HitBatch& hits, size_t begin, size_t end) {
    bvh_wide_trace_rays<Counters>(view, rays, hits, begin, end);
}

constexpr LeafBoxes kNone = LeafBoxes::None, kTri = LeafBoxes::Triangle,
                    kClip = LeafBoxes::Clipped;

}  // namespace

const KernelSet& kernel_set() {
    static const KernelSet set{
        BSPLAB_STR(BSPLAB_ISA_NS) + 4,  // "isa_avx2" -> "avx2"
        {{single_ray_entry<kNone, CountNothing>, single_ray_entry<kTri, CountNothing>,
          single_ray_entry<kClip, CountNothing>},
         {single_ray_entry<kNone, CountEvery>, single_ray_entry<kTri, CountEvery>,
          single_ray_entry<kClip, CountEvery>}},
        packet_entry,
        kLanes,
        {bvh_wide_entry<BvhCountNothing>, bvh_wide_entry<BvhCountEvery>},
        bvh_entry<BvhCountNothing>};
    return set;
}

}  // namespace bsp::BSPLAB_ISA_NS
