// Which tracing kernels run: the best instruction-set level this CPU has,
// or a lower one forced with the environment variable BSPLAB_ISA (sse2,
// avx2, avx512), so that one machine can test every level.
#pragma once
#include <string>
#include <vector>

#include "trace/kernels/kernel_set.hpp"

namespace bsp {

struct CpuFeatures {
    std::vector<std::string> supported;  // levels this CPU runs, lowest first
    std::string selected;                // the level the kernels use
    std::string forced;                  // BSPLAB_ISA's value, "" when unset
};

// Detected once per process (BSPLAB_ISA read then). Throws
// std::invalid_argument when BSPLAB_ISA names an unknown level or one this
// CPU lacks.
const CpuFeatures& cpu_features();
const KernelSet& selected_kernels();

}  // namespace bsp
