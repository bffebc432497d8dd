"""What the GUI checks under Xvfb (gui_check*.py) share: finding areas,
clicking with xdotool and grabbing the screen with ImageMagick's `import`.
Blender's window coordinates grow upwards, the screen's downwards."""

import subprocess

import bpy
import numpy as np


def areas(kind):
    """(window, area) of every area of `kind` in every window."""
    return [(w, a) for w in bpy.context.window_manager.windows for a in w.screen.areas
            if a.type == kind]


def click(window, x, y):
    """Left click at Blender window coordinates (origin bottom left)."""
    subprocess.run(["xdotool", "mousemove", str(int(x)), str(int(window.height - y)),
                    "click", "1"], check=False)


def grab_screen(png_path):
    """The whole screen as an (H, W, 3) uint8 array, row 0 at the top; also
    written to `png_path`. Read from an 8-bit PPM (a header and the raw
    bytes), so no image block and no colour management come between."""
    ppm = png_path.with_suffix(".ppm")
    subprocess.run(["import", "-window", "root", "-depth", "8", "ppm:" + str(ppm)], check=True)
    subprocess.run(["convert", str(ppm), str(png_path)], check=False)
    data = ppm.read_bytes()
    # P6 header: magic, width, height, maxval, each followed by whitespace.
    fields = data.split(maxsplit=4)
    width, height = int(fields[1]), int(fields[2])
    assert fields[3] == b"255", "expected an 8-bit PPM, got maxval {}".format(fields[3])
    pixels = np.frombuffer(fields[4][:width * height * 3], np.uint8)
    return pixels.reshape(height, width, 3)
