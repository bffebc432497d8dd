// One ray's walk through both levels of an instanced scene, recorded for the
// ray inspector: the top-level nodes it visits in order with the ray's range
// in each, and per instance entered the ray in its object space and the mesh
// tree's own recorded walk of it (trace_path.hpp). It is the single-ray
// trace's walk (top_walk.hpp's walk_top) with a policy that records, so its
// hit is intersect_instanced()'s bit for bit and so are its counts.
#pragma once
#include <cstdint>
#include <vector>

#include "instanced.hpp"
#include "trace/trace_path.hpp"

namespace bsp {

// A top-level node visited: its number (TopLevel::node's) and the ray's
// range in its box when the walk entered it (world units).
struct TopPathStep {
    uint32_t node;
    float t0, t1;
};

// An instance whose mesh tree the ray entered: the ray carried to its
// object space (the same t as the world ray's) and the tree's walk of it.
struct InstancePathVisit {
    uint32_t instance, mesh;
    float origin[3], direction[3];
    TracePath path;
};

// The walk, and - under TracePath's names - the closest hit ("prim" the
// triangle's index in its mesh) and the mesh trees' counts summed over the
// instances entered.
struct InstancedTracePath {
    std::vector<TopPathStep> top;
    std::vector<InstancePathVisit> instances;
    float t;  // inf on a miss
    int32_t prim = -1, instance = -1;
    int64_t flat_prim = -1;  // the hit's index in the flattened scene
    float u = 0, v = 0;
    uint32_t n_steps = 0, n_general_steps = 0, n_tests = 0, n_culled = 0, n_box_tests = 0;
    uint32_t n_top_steps = 0, n_instance_visits = 0;
};

// The ray o + t d, tmin < t < tmax, in world units; no culling (there is
// none in two levels).
InstancedTracePath trace_path(const InstancedScene& scene, const float o[3], const float d[3],
                              float tmin, float tmax);

}  // namespace bsp
