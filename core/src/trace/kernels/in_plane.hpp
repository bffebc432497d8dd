// The walk of a ray that lies in a split plane: which planes it lies in, and
// on which side of each the cell it is in lies.
//
// A ray lying in a node's plane (its crossing is NaN: a kd node's axis
// direction is 0 and the origin is on the split, or a general plane is
// parallel to the ray within the crossing error) visits both children, since
// either may hold its hit. Below such a node the walk is in a cell on one
// known side of that plane. A node further down that splits along the same
// plane then has a flat child on the other side: a cell of zero thickness,
// inside the plane. The builders make such cells to hold a plane's own
// triangles (a floor's, a wall's): on the fan scene half of the bsp_ize+kd
// tree's leaves are flat, and a ray lying in the floor walked them all (652
// steps per in-plane ray against 65 per camera ray).
//
// Skipping the flat child loses no hit. Every point of the flat cell lies in
// the plane, on the boundary of the cells on both sides of it, which the ray
// visits (it took both children of the first node). A triangle that is hit
// there and does not lie in the plane reaches into a cell on one side, which
// references it and accepts a hit on its boundary (leaf_acceptance.hpp). A
// triangle lying in the plane has a zero determinant in the watertight test
// for a ray lying in an axis plane (the shear along the zero direction
// component is exactly 0), so it is never hit; for a general plane a ray
// lying in it meets its triangles at rounding, as Embree does, and such a
// grazing hit is no part of the answer any path promises (oracle.leaks
// excuses rays within PARALLEL_COS of the plane). Every path takes this walk
// for such rays (single rays, counters, trace_path; packets hand them to it),
// so every path gives the same answer.
//
// The ordinary walk does not carry this state. A ray with a zero (or
// denormal) direction component, the only kind that can lie in a kd plane,
// takes the in-plane walk from the start; the ordinary walk gives up on a
// ray at the first general plane it is parallel to. The batch loop traces
// those rays after the others (single_ray.hpp: trace_rays, trace_ray_at), so
// rays that never lie in a plane pay nothing for it (bunny kd, hits only:
// +1.1 % instructions per random ray, +0.4 % per primary ray, callgrind).
#pragma once
#include <cstdint>
#include <cstring>

#include "tree.hpp"

namespace bsp {

// Which side of a remembered plane the walk's cell lies on (two bits per
// plane in InPlaneWalk::Sides).
enum class PlaneSide : uint32_t { Unknown = 0, Below = 1, Above = 2 };

struct InPlaneWalk {
    // The planes a ray lies in that it remembers, at most: a ray lies in one
    // plane, or two along an edge; more are rare and only cost the skip.
    static constexpr int kMaxPlanes = 8;
    using Sides = uint32_t;  // 2 bits per remembered plane
    static_assert(2 * kMaxPlanes <= 32, "the sides of every plane fit Sides");

    Plane planes[kMaxPlanes];
    int count = 0;

    // The index of `p` among the remembered planes (bitwise equal: a kd
    // split and a general node along the same axis plane are one plane),
    // remembering it if there is room; -1 when there is none.
    int index_of(const Plane& p) {
        for (int i = 0; i < count; ++i)
            if (std::memcmp(&planes[i], &p, sizeof(Plane)) == 0) return i;
        if (count == kMaxPlanes) return -1;
        planes[count] = p;
        return count++;
    }

    static PlaneSide side(Sides sides, int i) { return PlaneSide((sides >> (2 * i)) & 3u); }
    static Sides with(Sides sides, int i, PlaneSide s) {
        return sides | (uint32_t(s) << (2 * i));
    }
};

// The plane of a kd node along `axis` at `split`: n.x = d with n the axis.
inline Plane axis_plane(int axis, float split) {
    Plane p{0.0f, 0.0f, 0.0f, split};
    (axis == 0 ? p.nx : axis == 1 ? p.ny : p.nz) = 1.0f;
    return p;
}

}  // namespace bsp
