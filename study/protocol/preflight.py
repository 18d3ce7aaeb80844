"""``check_scenes(protocol)``: build every scene a protocol runs before a session starts.

The loader checks what it can without the arm model (ranges, joint limits, layout). Whether
each object's grasp pose can be reached from the start configuration (inverse kinematics) and
whether the scene compiles in MuJoCo is known only once the scene is built -- 0.1-0.3 s a scene,
cached for the trials that follow. The commands that start sessions (``serve``, ``run``,
``simulate``, ``sweep``, ``trial``, ``render``) call this first, so a scene that cannot run stops
them at once with the protocol's key path, never after the practice runs with a traceback.
"""

from __future__ import annotations

from app.robot import build_scene
from app.robot.errors import RobotError
from study.protocol.errors import ProtocolValueError
from study.protocol.protocol import Protocol


def check_scenes(protocol: Protocol) -> None:
    """Build every scene the protocol's tasks and training use; ``ProtocolValueError`` naming
    the scene's key when one cannot be built."""
    used = dict.fromkeys([*(t.scene for t in protocol.tasks), protocol.training.scene])
    for name in used:
        try:
            build_scene(protocol.scenes[name])
        except RobotError as exc:
            problem = str(exc).split(": ", 1)[-1] if str(exc).startswith("scenes.") else str(exc)
            raise ProtocolValueError(problem, file=protocol.path, key=f"scenes.{name}") from None
