// Run-time choice of the kernels' instruction-set level (cpu_dispatch.hpp).
#include "trace/cpu_dispatch.hpp"

#include <cstdlib>
#include <stdexcept>

namespace bsp {
namespace {

struct Level {
    const char* name;
    const KernelSet& (*kernels)();
    bool (*supported)();
};

// Lowest first. AVX-512 needs the F, VL, BW and DQ subsets the kernels are
// compiled with (CMakeLists.txt); AVX2 needs FMA, BMI1/2 too.
const Level kLevels[] = {
    {"sse2", isa_sse2::kernel_set, [] { return true; }},  // every x86-64 CPU
    {"avx2", isa_avx2::kernel_set,
     [] {
         return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma") &&
                __builtin_cpu_supports("bmi") && __builtin_cpu_supports("bmi2");
     }},
    {"avx512", isa_avx512::kernel_set,
     [] {
         return __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512vl") &&
                __builtin_cpu_supports("avx512bw") && __builtin_cpu_supports("avx512dq") &&
                __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma") &&
                __builtin_cpu_supports("bmi") && __builtin_cpu_supports("bmi2");
     }},
};

struct Choice {
    CpuFeatures features;
    const KernelSet* kernels = nullptr;
};

Choice choose() {
    __builtin_cpu_init();
    Choice c;
    const Level* best = nullptr;
    for (const Level& level : kLevels) {
        if (!level.supported()) continue;
        c.features.supported.push_back(level.name);
        best = &level;
    }
    const char* env = std::getenv("BSPLAB_ISA");
    if (env != nullptr && *env != '\0') {
        c.features.forced = env;
        const Level* wanted = nullptr;
        for (const Level& level : kLevels)
            if (c.features.forced == level.name) wanted = &level;
        if (wanted == nullptr)
            throw std::invalid_argument("BSPLAB_ISA=" + c.features.forced +
                                        ": unknown level (sse2, avx2 or avx512)");
        if (!wanted->supported())
            throw std::invalid_argument("BSPLAB_ISA=" + c.features.forced +
                                        ": this CPU does not support it");
        best = wanted;
    }
    c.features.selected = best->name;
    c.kernels = &best->kernels();
    return c;
}

const Choice& choice() {
    static const Choice c = choose();
    return c;
}

}  // namespace

const CpuFeatures& cpu_features() { return choice().features; }
const KernelSet& selected_kernels() { return *choice().kernels; }

}  // namespace bsp
