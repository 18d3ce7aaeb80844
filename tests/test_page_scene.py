"""The participant's scene as sent to the page (study.server.page_scene.SceneView), without a
browser: what nodes and options viser is asked to draw."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import viser

from app.robot.scene import build_scene
from study.protocol.loader import load_protocol
from study.server.page_scene import SceneView

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def model() -> Any:
    protocol = load_protocol(ROOT / "protocols" / "dragan2013.toml")
    return build_scene(next(iter(protocol.scenes.values()))).model


@pytest.fixture
def recorded() -> Iterator[tuple[viser.ViserServer, list[tuple[str, dict[str, Any]]]]]:
    """A viser server whose scene records every ``add_*`` call's keyword options."""
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    calls: list[tuple[str, dict[str, Any]]] = []
    for attr in dir(server.scene):
        method = getattr(server.scene, attr)
        if attr.startswith("add_") and callable(method):

            def record(*args: Any, _attr: str = attr, _method: Any = method, **kw: Any) -> Any:
                calls.append((_attr, dict(kw)))
                return _method(*args, **kw)

            setattr(server.scene, attr, record)
    try:
        yield server, calls
    finally:
        server.stop()


def test_without_shadows_no_surface_is_drawn_twice(model: Any, recorded: Any) -> None:
    """mjviser asks for a shadow-catching overlay (``receive_shadow=0.2``) on the table and the
    other fixed bodies; with no light casting shadows it is fully transparent, yet a software
    WebGL page shaded every table pixel twice for it (1366 x 768 at a fixed pixel ratio:
    13.0-13.7 -> 14.1-14.9 frames/s while the arm moves, benchmarks/README.md). The page sees
    the same scene without it, to the pixel."""
    server, calls = recorded
    SceneView(server, model, table_top=0.0)
    meshes = [(attr, kw) for attr, kw in calls if "receive_shadow" in kw]
    assert len(meshes) >= 2, calls  # the fixed bodies' meshes and the arm's batched meshes
    assert [kw["receive_shadow"] for _, kw in meshes] == [False] * len(meshes)
    assert not any(attr == "add_grid" for attr, _ in calls)  # the floor's grid is not drawn


def test_with_shadows_the_overlay_is_kept(model: Any, recorded: Any) -> None:
    """``shadows=True`` (lights that cast them) keeps mjviser's shadow-catching overlay."""
    server, calls = recorded
    SceneView(server, model, shadows=True, table_top=0.0)
    opacities = [kw["receive_shadow"] for _, kw in calls if "receive_shadow" in kw]
    assert 0.2 in opacities, opacities
