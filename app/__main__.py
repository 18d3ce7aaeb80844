"""``python -m app``: no commands any more; they moved to ``python -m study``.

``app`` is the simulated arm with blending and never reads a protocol or a store, so the study
server (``serve``), one headless trial (``trial``) and trial videos (``render``) now live with
the study: ``python -m study serve|trial|render`` take the same options as before.
"""

from __future__ import annotations

import sys

MOVED = {"serve": "serve", "trial": "trial", "render": "render"}


def main(argv: list[str]) -> int:
    command = next((a for a in argv if not a.startswith("-")), None)
    rest = " ".join(argv[1:]) if command else ""
    target = MOVED.get(command or "", "COMMAND")
    print(
        f"error: `python -m app {command or ''}` moved: run `python -m study {target}"
        f"{' ' + rest if rest else ''}` (see `python -m study --help`)",
        file=sys.stderr,
    )
    return 2


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
