// numpy's ray and hit columns as the core's RayBatch and HitBatch, their
// lengths checked once here for every binding that traces (trace.cpp,
// instanced.cpp): a wrong length is a clear error, never a read or a write
// past an array.
#pragma once
#include <cstddef>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string>

#include "bindings/arrays.hpp"
#include "trace/traverse.hpp"

namespace bsp::bindings {

// A counter column, or None for the hits-only path.
using Counter = std::optional<Out<uint32_t>>;

inline void check_length(size_t rays, size_t length, const char* what) {
    if (length != rays) throw std::invalid_argument(std::string(what) + " has the wrong length");
}

// tmin and tmax: one value for every ray, or one per ray.
inline RayBatch ray_batch(Vec3Array origins, Vec3Array directions, FloatIn tmin, FloatIn tmax) {
    const size_t n = origins.shape(0);
    check_length(n, directions.shape(0), "directions");
    if (tmin.shape(0) != 1) check_length(n, tmin.shape(0), "tmin");
    if (tmax.shape(0) != 1) check_length(n, tmax.shape(0), "tmax");
    RayBatch rays;
    rays.origins = origins.data();
    rays.directions = directions.data();
    rays.tmin = tmin.data();
    rays.tmax = tmax.data();
    rays.tmin_stride = tmin.shape(0) == 1 ? 0 : 1;
    rays.tmax_stride = tmax.shape(0) == 1 ? 0 : 1;
    rays.count = n;
    return rays;
}

inline uint32_t* counter_column(size_t rays, Counter& c, const char* what) {
    if (!c) return nullptr;
    check_length(rays, c->shape(0), what);
    return c->data();
}

// The hit columns and the five counters (all given or all None: the core
// rejects a mix).
inline HitBatch hit_batch(size_t rays, Out<float> t, Out<int32_t> prim, Out<float> u,
                          Out<float> v, Counter& steps, Counter& general_steps, Counter& tests,
                          Counter& culled, Counter& box_tests) {
    check_length(rays, t.shape(0), "t");
    check_length(rays, prim.shape(0), "prim");
    check_length(rays, u.shape(0), "u");
    check_length(rays, v.shape(0), "v");
    return HitBatch{t.data(),
                    prim.data(),
                    u.data(),
                    v.data(),
                    counter_column(rays, steps, "steps"),
                    counter_column(rays, general_steps, "general_steps"),
                    counter_column(rays, tests, "tests"),
                    counter_column(rays, culled, "culled"),
                    counter_column(rays, box_tests, "box_tests")};
}

// Rays over [0, inf) for the ordering's questions (orders_rays): the shared
// limits are constants, so the batch never outlives them.
inline RayBatch unlimited_rays(Vec3Array origins, Vec3Array directions) {
    static constexpr float kZero = 0.0f, kInf = std::numeric_limits<float>::infinity();
    if (origins.shape(0) != directions.shape(0))
        throw std::invalid_argument("origins and directions differ in length");
    RayBatch rays;
    rays.origins = origins.data();
    rays.directions = directions.data();
    rays.tmin = &kZero;
    rays.tmax = &kInf;
    rays.count = origins.shape(0);
    return rays;
}

// bsplab.checks.ray_order's index of "auto", "spatial" or "given".
inline RayOrder checked_ray_order(int order) {
    if (order < int(RayOrder::Auto) || order > int(RayOrder::Given))
        throw std::invalid_argument("ray_order: " + std::to_string(order) + " is not 0, 1 or 2");
    return RayOrder(order);
}

}  // namespace bsp::bindings
