"""Any plan line's scene: the renderer of each kind of recipe, by its ``kind``."""
from __future__ import annotations

from ..scene.recipe import Roots
from ..store.scene import Scene
from .mix import render_scene
from .recorded import render_recorded

RENDERERS = {"rendered": render_scene, "recorded": render_recorded}


def render_recipe(recipe, roots: Roots | None = None) -> Scene:
    """The scene of a rendered scene's recipe (:func:`~tsel_data.render.mix.render_scene`)
    or of a recorded one's (:func:`~tsel_data.render.recorded.render_recorded`)."""
    return RENDERERS[recipe.kind](recipe, roots if roots is not None else Roots())
