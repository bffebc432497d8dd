// How the per-ISA kernels keep a level's instructions out of other levels'
// code (trace/kernels/trace_kernels.cpp gives the rule, and
// cmake/check_kernel_objects.cmake checks it on the object files).
//
// Release builds make every kernel entry `flatten`: everything the entry
// calls, the shared inline functions included, is inlined into it. Sanitizer
// builds and the C++ unit tests' Debug build (CMake defines
// BSPLAB_KERNEL_NO_FLATTEN for their kernel objects) do not: flattening the
// instrumented kernels (-O1 + ASan + UBSan) took GCC 12 ten minutes a level
// on a 2-core CI machine against a minute and a half without, and the Debug
// build's 88 s a level. There the shared inline functions that the kernels
// call (the triangle test) are forced inline one by one instead, so the rule
// holds in those builds too; speed is not what they are for.
#pragma once

#ifdef BSPLAB_KERNEL_NO_FLATTEN
#define BSPLAB_KERNEL_FLATTEN
#define BSPLAB_KERNEL_SHARED_INLINE __attribute__((always_inline)) inline
#else
#define BSPLAB_KERNEL_FLATTEN __attribute__((flatten))
#define BSPLAB_KERNEL_SHARED_INLINE inline
#endif
