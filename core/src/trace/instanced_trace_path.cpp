#include "trace/instanced_trace_path.hpp"

#include <limits>

#include "trace/top_walk.hpp"

namespace bsp {
namespace {

// walk_top's policy that records: each top-level visit with its node and
// range, each instance entered with the mesh tree's recorded walk, whose
// hit is the tree's intersect() hit (trace_path.hpp), as the single-ray
// trace's kernel finds it.
struct RecordTop {
    static constexpr bool kRecords = true;
    const InstancedScene& scene;
    InstancedTracePath& out;

    void top_step(const top_walk::TopVisit& v) {
        out.top.push_back({v.node, v.t0, v.t1});
        ++out.n_top_steps;
    }
    void trace_instance(uint32_t id, const Instance& inst, const float ob[3], const float db[3],
                        float tmin, float limit, top_walk::BottomHit& h) {
        InstancePathVisit visit{id, inst.mesh, {ob[0], ob[1], ob[2]}, {db[0], db[1], db[2]},
                                trace_path(*scene.meshes[inst.mesh], ob, db, tmin, limit, false)};
        const TracePath& p = visit.path;
        ++out.n_instance_visits;
        out.n_steps += p.n_steps;
        out.n_general_steps += p.n_general_steps;
        out.n_tests += p.n_tests;
        out.n_culled += p.n_culled;
        out.n_box_tests += p.n_box_tests;
        h = {p.t, p.u, p.v, p.prim};
        out.instances.push_back(std::move(visit));
    }
};

}  // namespace

InstancedTracePath trace_path(const InstancedScene& scene, const float o[3], const float d[3],
                              float tmin, float tmax) {
    InstancedTracePath out;
    const top_walk::TopRay ray(o, d, top_walk::scene_max_of(scene));
    const double od[3] = {o[0], o[1], o[2]}, dd[3] = {d[0], d[1], d[2]};
    top_walk::Closest best;
    best.t = tmax;
    RecordTop record{scene, out};
    top_walk::walk_top(scene, ray, od, dd, tmin, tmax, best, record);
    const bool hit = best.prim >= 0;
    out.t = hit ? best.t : std::numeric_limits<float>::infinity();
    out.prim = best.prim;
    out.instance = best.instance;
    out.flat_prim = hit ? int64_t(best.flat) : -1;
    out.u = best.u;
    out.v = best.v;
    return out;
}

}  // namespace bsp
