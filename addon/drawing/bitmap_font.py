# SPDX-License-Identifier: GPL-3.0-or-later
"""A tiny bitmap font drawn with numpy: text in the add-on's images.

Why not `blf` into a `gpu` offscreen buffer: GPU drawing raises in
background mode (`blender -b`, the bpy module: every test and every
headless demo), so the labels would exist only in an interactive Blender.
The glyphs below (5 x 7 pixels, capitals, digits and the punctuation the
plots need; a few hundred bytes, drawn for this add-on) work everywhere and
draw the same pixels on every Blender version. Lower-case text is drawn in
capitals.
"""

import numpy as np

GLYPH_W, GLYPH_H = 5, 7
ADVANCE = GLYPH_W + 1  # one blank column between characters
LINE_H = GLYPH_H + 2

# Each glyph: 7 rows of 5 columns, top row first; '#' is ink.
_GLYPHS = {
    "A": ".###.|#...#|#...#|#####|#...#|#...#|#...#",
    "B": "####.|#...#|#...#|####.|#...#|#...#|####.",
    "C": ".###.|#...#|#....|#....|#....|#...#|.###.",
    "D": "####.|#...#|#...#|#...#|#...#|#...#|####.",
    "E": "#####|#....|#....|####.|#....|#....|#####",
    "F": "#####|#....|#....|####.|#....|#....|#....",
    "G": ".###.|#...#|#....|#.###|#...#|#...#|.####",
    "H": "#...#|#...#|#...#|#####|#...#|#...#|#...#",
    "I": ".###.|..#..|..#..|..#..|..#..|..#..|.###.",
    "J": "..###|...#.|...#.|...#.|...#.|#..#.|.##..",
    "K": "#...#|#..#.|#.#..|##...|#.#..|#..#.|#...#",
    "L": "#....|#....|#....|#....|#....|#....|#####",
    "M": "#...#|##.##|#.#.#|#.#.#|#...#|#...#|#...#",
    "N": "#...#|#...#|##..#|#.#.#|#..##|#...#|#...#",
    "O": ".###.|#...#|#...#|#...#|#...#|#...#|.###.",
    "P": "####.|#...#|#...#|####.|#....|#....|#....",
    "Q": ".###.|#...#|#...#|#...#|#.#.#|#..#.|.##.#",
    "R": "####.|#...#|#...#|####.|#.#..|#..#.|#...#",
    "S": ".####|#....|#....|.###.|....#|....#|####.",
    "T": "#####|..#..|..#..|..#..|..#..|..#..|..#..",
    "U": "#...#|#...#|#...#|#...#|#...#|#...#|.###.",
    "V": "#...#|#...#|#...#|#...#|#...#|.#.#.|..#..",
    "W": "#...#|#...#|#...#|#.#.#|#.#.#|#.#.#|.#.#.",
    "X": "#...#|#...#|.#.#.|..#..|.#.#.|#...#|#...#",
    "Y": "#...#|#...#|.#.#.|..#..|..#..|..#..|..#..",
    "Z": "#####|....#|...#.|..#..|.#...|#....|#####",
    "0": ".###.|#...#|#..##|#.#.#|##..#|#...#|.###.",
    "1": "..#..|.##..|..#..|..#..|..#..|..#..|.###.",
    "2": ".###.|#...#|....#|...#.|..#..|.#...|#####",
    "3": "####.|....#|....#|.###.|....#|....#|####.",
    "4": "...#.|..##.|.#.#.|#..#.|#####|...#.|...#.",
    "5": "#####|#....|####.|....#|....#|#...#|.###.",
    "6": "..##.|.#...|#....|####.|#...#|#...#|.###.",
    "7": "#####|....#|...#.|..#..|.#...|.#...|.#...",
    "8": ".###.|#...#|#...#|.###.|#...#|#...#|.###.",
    "9": ".###.|#...#|#...#|.####|....#|...#.|.##..",
    ".": ".....|.....|.....|.....|.....|.##..|.##..",
    ",": ".....|.....|.....|.....|.##..|..#..|.#...",
    ":": ".....|.##..|.##..|.....|.##..|.##..|.....",
    "-": ".....|.....|.....|#####|.....|.....|.....",
    "+": ".....|..#..|..#..|#####|..#..|..#..|.....",
    "_": ".....|.....|.....|.....|.....|.....|#####",
    "%": "##...|##..#|...#.|..#..|.#...|#..##|...##",
    "/": ".....|....#|...#.|..#..|.#...|#....|.....",
    "(": "...#.|..#..|.#...|.#...|.#...|..#..|...#.",
    ")": ".#...|..#..|...#.|...#.|...#.|..#..|.#...",
    "=": ".....|.....|#####|.....|#####|.....|.....",
    "×": ".....|#...#|.#.#.|..#..|.#.#.|#...#|.....",
    "<": "...#.|..#..|.#...|#....|.#...|..#..|...#.",
    ">": ".#...|..#..|...#.|....#|...#.|..#..|.#...",
    "'": "..#..|..#..|.....|.....|.....|.....|.....",
    " ": ".....|.....|.....|.....|.....|.....|.....",
    "?": ".###.|#...#|....#|...#.|..#..|.....|..#..",
}


def _bitmap(rows):
    return np.array([[c == "#" for c in row] for row in rows.split("|")], dtype=bool)


GLYPHS = {ch: _bitmap(rows) for ch, rows in _GLYPHS.items()}
UNKNOWN = GLYPHS["?"]


def text_size(text, scale=1):
    """(width, height) in pixels of `text` on one line at `scale`."""
    if scale < 1:
        raise ValueError("text scale must be at least 1, got {}".format(scale))
    width = max(0, len(text) * ADVANCE - 1)
    return width * scale, GLYPH_H * scale


def text_mask(text, scale=1):
    """A (height, width) bool mask of `text`: True where there is ink."""
    width, height = text_size(text, scale)
    mask = np.zeros((GLYPH_H, max(0, len(text) * ADVANCE - 1)), dtype=bool)
    for i, ch in enumerate(text.upper()):
        mask[:, i * ADVANCE:i * ADVANCE + GLYPH_W] = GLYPHS.get(ch, UNKNOWN)
    # Each glyph pixel becomes a scale x scale block.
    return np.kron(mask, np.ones((scale, scale), dtype=bool)).reshape(height, width)


def draw_text(img, text, x, y, colour, scale=1, anchor="left"):
    """Draw `text` into the (H, W, >=3) image with its top at row y; row 0 is
    the top. `anchor` says what x is: the text's "left" edge, "right" edge or
    "centre". Ink outside the image is clipped. Returns the text's box
    (x0, y0, x1, y1), x1 and y1 exclusive."""
    mask = text_mask(text, scale)
    h, w = mask.shape
    offsets = {"left": 0, "right": w, "centre": w // 2}
    if anchor not in offsets:
        raise ValueError("anchor must be one of {}, got {!r}".format(", ".join(offsets), anchor))
    x0, y0 = int(x) - offsets[anchor], int(y)
    # The part of the mask that lands inside the image.
    ih, iw = img.shape[:2]
    cx0, cy0 = max(0, x0), max(0, y0)
    cx1, cy1 = min(iw, x0 + w), min(ih, y0 + h)
    if cx0 < cx1 and cy0 < cy1:
        sub = mask[cy0 - y0:cy1 - y0, cx0 - x0:cx1 - x0]
        img[cy0:cy1, cx0:cx1, :3][sub] = colour
    return x0, y0, x0 + w, y0 + h
