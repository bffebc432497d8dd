// Exact-or-padded bounds of a triangle clipped to a box ("perfect splits").
#pragma once
#include "geometry.hpp"

namespace bsp {

// Bounds of the part of `tri` inside `box`, or an empty box when the triangle
// misses it. Coordinates created by the clip carry a small outward pad, so the
// result always contains the true clipped triangle: a bound that rounded
// inwards could drop a triangle from a cell it really reaches.
Box clipped_bounds(const Triangle& tri, const Box& box);

// The bounds of the parts of `tri` inside `box` on either side of the plane
// x[axis] = pos: one clip to the box, then one split of the polygon.
void split_clipped_bounds(const Triangle& tri, const Box& box, int axis, float pos, Box& below,
                          Box& above);

}  // namespace bsp
