# SPDX-License-Identifier: GPL-3.0-or-later
"""A/B comparison: the preview of two trees side by side or as a difference.

Build & Render with "Compare with B" on builds and renders a second tree (B)
with the camera, mode and culling of the first (A). Its preview is one of

- `split`: A's image left of the middle column, B's right of it, a line
  between in a colour no render mode produces;
- `diff_steps` / `diff_tests` / `diff_box_tests`: per pixel B's count minus
  A's (traversal steps, triangle tests or, a BVH's, ray-box tests of that
  pixel's camera ray: 0 on a kd or BSP tree), in diverging colours (blue:
  B does less, red: B does more, exactly 0: white, on a square-root scale)
  on a symmetric range +-S, with a colour bar labelled -S / 0 / +S. S is the 99th percentile of
  the non-zero |B - A| (not their maximum: one outlier pixel would wash out
  the whole map); the few pixels beyond it take the end colours, and the
  bar's caption says how many.

Pure numpy, no bpy: the job's worker thread hands the images and per-pixel
counters here, and addon/tests/test_compare_job.py tests
the composition without Blender.
"""

import numpy as np

from ..drawing import legend

# The preview views, and for the differences the per-pixel counter they show.
VIEWS = {"split": None, "diff_steps": "steps", "diff_tests": "tests",
         "diff_box_tests": "box_tests"}
UNITS = {"steps": "traversal steps per ray", "tests": "triangle tests per ray",
         "box_tests": "box tests per ray"}

# Magenta: the heat ramp has no magenta, the shaded and depth modes are grey,
# and a normal map shows it only for a normal of (1, -1, 1) / 1, not a unit one.
SPLIT_LINE = (1.0, 0.0, 1.0)
SPLIT_LINE_WIDTH = 2

# The ends of the diverging map; the middle (0) is white.
FEWER = np.array([0.13, 0.37, 0.80], np.float32)  # B does less work than A
MORE = np.array([0.80, 0.13, 0.10], np.float32)   # B does more work than A


def split_column(width):
    """The first column of B's half; the line covers the column before it
    and this one."""
    return width // 2


def split_columns(width):
    """The columns [start, stop) the split line covers."""
    column = split_column(width)
    return column - SPLIT_LINE_WIDTH // 2, column + (SPLIT_LINE_WIDTH + 1) // 2


def _check_pair(a, b, what):
    a, b = np.asarray(a), np.asarray(b)
    if a.shape != b.shape:
        raise ValueError("A's and B's {} differ in shape: {} and {}".format(what, a.shape, b.shape))
    return a, b


def split_image(a, b):
    """(H, W, 4): A's pixels left of the split column, B's right of it, the
    split line between. Every pixel outside the line is A's or B's own, so
    pixel (x, y) is still camera ray (x, y) of the tree shown there."""
    a, b = _check_pair(a, b, "images")
    if a.ndim != 3 or a.shape[2] != 4 or a.shape[1] < SPLIT_LINE_WIDTH + 2:
        raise ValueError("a split needs two (H, W, 4) images at least {} px wide, got {}".format(
            SPLIT_LINE_WIDTH + 2, a.shape))
    out = np.array(b, dtype=np.float32)
    column = split_column(a.shape[1])
    out[:, :column] = a[:, :column]
    start, stop = split_columns(a.shape[1])
    out[:, start:stop, :3] = SPLIT_LINE
    out[:, start:stop, 3] = 1.0
    return out


def diverging(x):
    """Colours of values x in [-1, 1]: FEWER at -1, white at 0 (exactly
    1.0, 1.0, 1.0), MORE at +1."""
    x = np.clip(np.asarray(x, dtype=np.float32), -1.0, 1.0)[..., None]
    end = np.where(x < 0, FEWER, MORE)
    return (1.0 + np.abs(x) * (end - 1.0)).astype(np.float32)


def difference_colours(x):
    """Colours of differences x in units of the map's range (+-1 at +-S):
    diverging() of sign(x) sqrt(|x|). Most pixels differ by a step or two
    while the range is set by the larger differences; the square root keeps
    the small ones visible, and the bar (diverging_ramp) uses the same map,
    so a colour still reads off the bar at its value."""
    x = np.clip(np.asarray(x, dtype=np.float32), -1.0, 1.0)
    return diverging(np.sign(x) * np.sqrt(np.abs(x)))


def diverging_ramp(t):
    """The difference map on [0, 1] (0: -S, 0.5: 0, 1: +S), for the bar."""
    return difference_colours(2.0 * np.asarray(t, dtype=np.float32) - 1.0)


def difference(a_counts, b_counts):
    """Per pixel B - A (int64) and max |B - A|."""
    a, b = _check_pair(a_counts, b_counts, "counters")
    diff = b.astype(np.int64) - a.astype(np.int64)
    return diff, int(np.abs(diff).max(initial=0))


# The share of the differing pixels whose |B - A| the map's range covers.
RANGE_PERCENTILE = 99.0


def difference_scale(diff):
    """The map's range S: the RANGE_PERCENTILE-th percentile of the non-zero
    |diff|, rounded up (0 when A and B count the same everywhere)."""
    nonzero = np.abs(diff[diff != 0])
    if nonzero.size == 0:
        return 0
    return int(np.ceil(np.percentile(nonzero, RANGE_PERCENTILE)))


def difference_image(a_counts, b_counts):
    """(H, W, 4) diverging map of B - A on +-S (difference_scale; all white
    when A and B count the same everywhere), S, and the share of pixels
    beyond +-S (drawn in the end colours)."""
    diff, _ = difference(a_counts, b_counts)
    scale = difference_scale(diff)
    image = np.ones(diff.shape + (4,), np.float32)
    image[..., :3] = difference_colours(diff / max(scale, 1))
    clipped = float(np.count_nonzero(np.abs(diff) > scale)) / max(diff.size, 1)
    return image, scale, clipped


def with_difference_bar(image, scale, counter, clipped=0.0):
    """The difference map with its bar below: -S / 0 / +S, the unit, and the
    share of pixels beyond +-S when there are any."""
    caption = "B - A, {}".format(UNITS[counter])
    if scale == 0:
        caption += ": equal everywhere"
    elif clipped > 0:
        caption += " ({:.2g} % beyond +-{})".format(100.0 * clipped, scale)
    return legend.with_colour_bar(image, scale, diverging_ramp, caption,
                                  low="-{}".format(scale) if scale else "0", middle="0")


def heat_split(a_counts, b_counts, mode, ramp):
    """A's and B's heat images on one scale, 0 .. max over both (at least 1),
    so that a colour means the same count in both halves; and that max."""
    a, b = _check_pair(a_counts, b_counts, "counters")
    top = max(int(a.max(initial=0)), int(b.max(initial=0)), 1)
    images = []
    for counts in (a, b):
        image = np.ones(counts.shape + (4,), np.float32)
        image[..., :3] = ramp(counts.astype(np.float32) / top)
        images.append(image)
    return images[0], images[1], top


def heat_counter(mode):
    """The per-pixel counter a heat mode shows ("steps", ...), or None."""
    if mode not in legend.HEAT_UNITS:
        return None
    return legend.HEAT_UNITS[mode][0][len("max_"):]


def preview(a_image, b_image, counts, mode, view, ramp):
    """The preview image of an A/B press.

    `counts` holds "a" and "b", each a dict of (H, W) per-pixel counters
    ("steps", "tests", "culled", "box_tests"); it may be None for a split of a mode that
    shows no counter. `ramp` is the core's heat ramp."""
    if view not in VIEWS:
        raise ValueError("unknown comparison view {!r}; views: {}".format(view, ", ".join(VIEWS)))
    counter = VIEWS[view]
    if counter is not None:
        image, scale, clipped = difference_image(counts["a"][counter], counts["b"][counter])
        return with_difference_bar(image, scale, counter, clipped)
    shown = heat_counter(mode)
    if shown is None:
        return split_image(a_image, b_image)
    a_image, b_image, top = heat_split(counts["a"][shown], counts["b"][shown], mode, ramp)
    return legend.with_colour_bar(split_image(a_image, b_image), top, ramp,
                                  legend.HEAT_UNITS[mode][1])


def needs_counts(mode, view):
    """Whether the preview needs the per-pixel counters of both trees."""
    return VIEWS.get(view) is not None or heat_counter(mode) is not None
