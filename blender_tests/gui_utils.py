"""What the GUI checks under Xvfb (gui_check*.py) share: finding areas,
clicking with xdotool, drawing the window now, grabbing the screen with
ImageMagick's `import`, and waiting for a condition on Blender's timer.
Blender's window coordinates grow upwards, the screen's downwards.

The checks run as a timer's steps, so that Blender handles its events
(xdotool's clicks and keys, the modal operators' timers) in between. Nothing
waits a fixed time: a step that needs an effect (a job ended, a click
handled) waits for that effect with `Waits` (a time-out only a failing check
reaches), and a screenshot first draws the window (`redraw_window`)."""

import subprocess
import time

import bpy
import numpy as np

# How often a waiting step looks again, and how long it waits at most: only
# a failing check reaches the time-out (a build, a render or a click's
# handling on a loaded 2-core machine takes seconds, not minutes).
POLL_SECONDS = 0.1
TIMEOUT_SECONDS = 120.0


def areas(kind):
    """(window, area) of every area of `kind` in every window."""
    return [(w, a) for w in bpy.context.window_manager.windows for a in w.screen.areas
            if a.type == kind]


def click(window, x, y):
    """Left click at Blender window coordinates (origin bottom left)."""
    subprocess.run(["xdotool", "mousemove", str(int(x)), str(int(window.height - y)),
                    "click", "1"], check=True)


def redraw_window():
    """Draw the whole window and swap it to the screen now, so that a
    screenshot taken next shows the current state (the areas changed, the
    image shown, the overlay toggled), not a frame from before."""
    window = bpy.context.window_manager.windows[0]
    area = max(window.screen.areas, key=lambda a: a.width * a.height)
    region = next(r for r in area.regions if r.type == 'WINDOW')
    with bpy.context.temp_override(window=window, area=area, region=region):
        bpy.ops.wm.redraw_timer(type='DRAW_WIN_SWAP', iterations=1)


def grab_screen(png_path):
    """The whole screen as an (H, W, 3) uint8 array, row 0 at the top, after
    drawing the window; also written to `png_path`. Read from an 8-bit PPM
    (a header and the raw bytes), so no image block and no colour management
    come between."""
    redraw_window()
    ppm = png_path.with_suffix(".ppm")
    subprocess.run(["import", "-window", "root", "-depth", "8", "ppm:" + str(ppm)], check=True)
    subprocess.run(["convert", str(ppm), str(png_path)], check=True)
    data = ppm.read_bytes()
    ppm.unlink()
    # P6 header: magic, width, height, maxval, each followed by whitespace.
    fields = data.split(maxsplit=4)
    width, height = int(fields[1]), int(fields[2])
    assert fields[3] == b"255", "expected an 8-bit PPM, got maxval {}".format(fields[3])
    pixels = np.frombuffer(fields[4][:width * height * 3], np.uint8)
    return pixels.reshape(height, width, 3)


class Waits:
    """The check's waits for conditions, one at a time, by name:
    `until(name, condition)` is True once `condition()` holds, False while
    it does not yet (the step returns POLL_SECONDS to be called again), and
    raises TimeoutError past `timeout` seconds since the first call with
    that name, naming what it waited for."""

    def __init__(self):
        self._since = {}

    def until(self, name, condition, timeout=TIMEOUT_SECONDS):
        start = self._since.setdefault(name, time.monotonic())
        if condition():
            del self._since[name]
            return True
        if time.monotonic() - start > timeout:
            raise TimeoutError("waited {:.0f} s for {}".format(timeout, name))
        return False
