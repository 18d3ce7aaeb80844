"""Where the Franka Panda model comes from: the ``example-robot-data`` package, read offline.

The URDF's ``package://`` paths are resolved to the installed files and the ``.dae`` visuals
are swapped for the STL collision meshes (MuJoCo cannot read COLLADA). Nothing is downloaded.
"""

from __future__ import annotations

import functools
import os
import re
import sys
from pathlib import Path

from app.robot.errors import ModelNotFoundError

_RELATIVE = Path("share") / "example-robot-data" / "robots" / "panda_description"
_PACKAGE_URI = "package://example-robot-data/robots/panda_description"
INSTALL_HINT = (
    "install it with `pip install example-robot-data` into this environment, or point"
    " PANDA_DESCRIPTION_DIR at a directory holding urdf/panda.urdf and meshes/collision/*.stl"
)


def _candidates() -> list[Path]:
    out = []
    env = os.environ.get("PANDA_DESCRIPTION_DIR")
    if env:
        out.append(Path(env))
    for entry in [sys.prefix, *sys.path]:
        if entry:
            out.append(Path(entry) / "cmeel.prefix" / _RELATIVE)
    out.append(Path(sys.prefix) / _RELATIVE)
    return out


@functools.cache
def panda_description_dir() -> Path:
    """The installed ``panda_description`` directory; ``ModelNotFoundError`` says how to install."""
    tried = _candidates()
    for path in tried:
        if (path / "urdf" / "panda.urdf").is_file():
            return path.resolve()
    raise ModelNotFoundError(
        "Franka Panda model not found (looked for urdf/panda.urdf under "
        f"{', '.join(str(p) for p in tried[:3])}, ...): {INSTALL_HINT}"
    )


@functools.cache
def panda_urdf() -> str:
    """The Panda URDF with absolute mesh paths and STL meshes for the visuals."""
    root = panda_description_dir()
    text = (root / "urdf" / "panda.urdf").read_text()
    text = text.replace(_PACKAGE_URI, str(root))
    text = re.sub(r"meshes/visual/(\w+)\.dae", r"meshes/collision/\1.stl", text)
    for mesh in re.findall(r'filename="([^"]+)"', text):
        if "finger" not in mesh and not Path(mesh).is_file():
            raise ModelNotFoundError(f"Panda mesh {mesh} is missing: {INSTALL_HINT}")
    return text
