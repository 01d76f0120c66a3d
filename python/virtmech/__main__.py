"""``python -m virtmech``: the virtmech command; ``python -m virtmech --cmake-dir`` prints the
folder of the installed CMake package (the core's headers, static library and
virtmechConfig.cmake), for CMAKE_PREFIX_PATH when building a plugin."""

import sys
from pathlib import Path

if sys.argv[1:] == ["--cmake-dir"]:
    print(Path(__file__).resolve().parent / "lib" / "cmake")
    sys.exit(0)

from .cli import main  # noqa: E402

sys.exit(main())
