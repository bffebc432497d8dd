"""Run the add-on's pytest suite inside a Blender binary.

    blender --background --factory-startup -noaudio --python-exit-code 1 \\
        --python blender_tests/run_in_blender.py [-- PYTEST_ARGS...]

Blender's Python ignores PYTHONPATH, so the directories that hold the
`bsplab` core (and `embreex`) are passed in BSPLAB_PYTHONPATH (os.pathsep
separated). pytest itself comes from Blender's Python (Debian's Blender uses
the system Python: `apt-get install python3-pytest`). Exits with pytest's
exit code.
"""

import os
import pathlib
import sys

HERE = pathlib.Path(__file__).resolve().parent


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    for entry in reversed(os.environ.get("BSPLAB_PYTHONPATH", "").split(os.pathsep)):
        if entry and entry not in sys.path:
            sys.path.insert(0, entry)
    sys.path.insert(0, str(HERE))
    try:
        import pytest
    except ImportError:
        print("run_in_blender: pytest is not importable in Blender's Python "
              "(Debian: apt-get install python3-pytest)", file=sys.stderr)
        return 2
    # No cache dir: the source tree may be read-only, and nothing needs it.
    return int(pytest.main(["-p", "no:cacheprovider", "-ra", str(HERE), *argv]))


if __name__ == "__main__":
    code = main()
    sys.stdout.flush()
    sys.stderr.flush()
    # sys.exit in a --python script makes Blender quit with that code.
    sys.exit(code)
