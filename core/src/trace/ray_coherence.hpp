// Whether a batch of rays is coherent: in the order it comes, do
// neighbouring rays run the same way, or start in the same place? The
// answers pick between ways of tracing that give the same hits (the
// kernel's loop, the spatial order of ray_order.hpp); a wrong one costs
// speed only. Compiled once, for any x86-64: the kernels of every
// instruction-set level call the same functions.
#pragma once
#include <cstddef>

#include "trace/traverse.hpp"

namespace bsp {

// Whether a range of rays is coherent: neighbours in the batch run in
// nearly the same direction (camera rays in pixel or tile order). Up to
// kCoherenceSamples pairs of neighbours, spread over [begin, end), are
// compared: coherent when at least half of them are less than about 8
// degrees apart (cosine > 0.99). Camera rays are far closer than that (a
// 512-pixel image of a 60-degree view: 0.1 degree), random directions
// almost never are.
constexpr size_t kCoherenceSamples = 32;
bool rays_are_coherent(const RayBatch& rays, size_t begin, size_t end);

// Whether consecutive rays already start near each other: up to
// kCoherenceSamples rays spread over the batch, each compared with its
// neighbour and with the ray half a batch away; the batch is in spatial
// order when, for at least half of them, the neighbour's origin is within
// kOrderedOriginShare of the distance to the far one. Secondary rays cast
// from a camera's hits in pixel order are (an ambient-occlusion pass's),
// random rays are not.
constexpr float kOrderedOriginShare = 1.0f / 32.0f;
bool origins_are_coherent(const RayBatch& rays);

}  // namespace bsp
