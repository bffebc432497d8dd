// One ray's walk through the tree, recorded step by step for the ray
// inspector: the nodes it visits in order with the ray's range in each, the
// triangles each leaf tests and what came of them, and the closest hit.
// It is the single-ray kernel's own loop (kernels/single_ray.hpp) with a
// policy that records instead of counting, so its hit is intersect()'s bit
// for bit and its counts are intersect()'s steps, tests and culled.
#pragma once
#include <cstdint>
#include <vector>

#include "tree.hpp"

namespace bsp {

// What happened to one triangle reference of a visited leaf.
enum class TestResult : uint8_t {
    Miss = 0,    // tested, no closer hit
    Hit = 1,     // tested, the closest hit so far
    Culled = 2,  // its box misses the ray segment's box (culling only): not tested
    Seen = 3,    // already tested by this ray in an earlier leaf (mailbox): not tested
};

struct PathStep {
    uint32_t node;
    int32_t depth;
    uint8_t kind;   // NodeKind (a BVH's: Box or Leaf)
    double t0, t1;  // the ray's range in the node's cell (a BVH's: box) when visited (world units)
};

struct PathTest {
    uint32_t step;  // the leaf's index in TracePath::steps
    uint32_t prim;
    TestResult result;
    float t;  // the hit distance for Hit, NaN otherwise
};

struct TracePath {
    std::vector<PathStep> steps;
    std::vector<PathTest> tests;
    float t;  // inf on a miss
    int32_t prim = -1;
    float u = 0, v = 0;
    uint32_t n_steps = 0, n_general_steps = 0, n_tests = 0, n_culled = 0, n_box_tests = 0;
};

// The ray o + t d, tmin < t < tmax, in world units. With `cull`, leaves skip
// triangles by their boxes as intersect(cull=True) does. A BVH's walk is its
// kernel's (kernels/bvh_single_ray.hpp), for which cull changes nothing.
TracePath trace_path(const Tree& tree, const float o[3], const float d[3], float tmin, float tmax,
                     bool cull);

}  // namespace bsp
