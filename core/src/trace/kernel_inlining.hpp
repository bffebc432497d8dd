// How the per-ISA kernels keep a level's instructions out of other levels'
// code (trace/kernels/trace_kernels.cpp gives the rule, and
// cmake/check_kernel_objects.cmake checks it on the object files).
//
// Release and Debug builds make every kernel entry `flatten`: everything the
// entry calls, the shared inline functions included, is inlined into it.
// Sanitizer builds (CMake defines BSPLAB_KERNEL_NO_FLATTEN for their kernel
// objects) do not: flattening the instrumented kernels (-O1 + ASan + UBSan)
// took GCC 12 about ten minutes a level, against one without, and a third of
// CI's time budget. There the shared inline functions that the kernels call
// (the triangle test) are forced inline one by one instead, so the rule holds
// in those builds too.
#pragma once

#ifdef BSPLAB_KERNEL_NO_FLATTEN
#define BSPLAB_KERNEL_FLATTEN
#define BSPLAB_KERNEL_SHARED_INLINE __attribute__((always_inline)) inline
#else
#define BSPLAB_KERNEL_FLATTEN __attribute__((flatten))
#define BSPLAB_KERNEL_SHARED_INLINE inline
#endif
