"""Each source of a stored scene alone: rendered again from the scene's recipe.

A dataset keeps only the mixture. Its plan (``plan/{split}.jsonl``) holds the recipe of
every scene, and a recipe determines its scene, so the renderer can give the target
alone and each interferer alone, exactly as they sound in the mix (same RIRs, gains and
anti-clipping gain: the stems add up to the stored mixture). ``tsel inspect --wav``
writes them as headphone previews (:mod:`tsel_data.receivers.stereo`).

This needs what rendering needs: the plan file and the clips (and the RIR bank) the
recipe names, where the plan says they are (relative to the dataset folder), or where
``corpus_dir`` and ``bank`` say. From Python::

    scene = find_scene("DIR", "test/0")
    stems, same = render_stems(scene_recipe("DIR", "test", 0, scene.scene_id), scene.audio)
"""
from __future__ import annotations

import os

import numpy as np

from ..corpus.audio import save_wav
from ..errors import DatasetError
from ..receivers.stereo import stereo_preview
from ..render.mix import mix_parts
from ..scene.recipe import Roots, SceneRecipe, recipe_from_line
from ..store.integrity import input_stats, missing_inputs
from ..store.layout import Layout
from ..store.plans import read_plan_lines
from .shards import open_plan

# The stored mixture and the one rendered again agree to float32 rounding; more means the
# clips or the bank changed since the dataset was made.
MATCH_TOLERANCE = 1e-4


def scene_recipe(root: str, split: str, index: int, scene_id: str | None = None, corpus_dir: str | None = None,
                 bank: str | None = None, as_stored: bool = False) -> SceneRecipe:
    """The recipe of scene ``index`` of ``split`` from the dataset's plan, with the files
    it names as paths on this machine (where the plan says, relative to the dataset, or
    in ``corpus_dir`` and ``bank``), so :func:`render_stems` and ``render_scene`` read it
    as it is. ``scene_id``: the scene it must be (a plan of other shards is refused).
    ``as_stored``: as the plan holds it (clips named relative to the corpus)."""
    layout = Layout(root)
    lines = read_plan_lines(layout, split)
    shown = scene_id or f"{split}/{index}"
    if not 0 <= index < len(lines):
        raise DatasetError(f"{layout.plan_file(split)} has no recipe for {shown} (the plan is missing or "
                           f"shorter); the stems are rendered from the scene's recipe")
    recipe = recipe_from_line(layout.plan_file(split), index + 1, lines[index])
    if recipe.kind != "rendered":
        raise DatasetError(f"{recipe.scene_id} is a recorded scene: its sources were recorded together and have no "
                           f"stems")
    if scene_id is not None and recipe.scene_id != scene_id:
        raise DatasetError(f"{layout.plan_file(split)}: line {index + 1} is {recipe.scene_id}, not {scene_id}; the "
                           f"plan does not belong to these shards")
    return recipe if as_stored else dataset_roots(root, corpus_dir, bank).resolve(recipe)


def dataset_roots(root: str, corpus_dir: str | None = None, bank: str | None = None) -> Roots:
    """Where the files of a dataset's recipes are: as its plan says, or as given."""
    return open_plan(root, corpus_dir, bank).roots


def render_stems(recipe: SceneRecipe, mixture: np.ndarray | None = None,
                 roots: Roots | None = None, receiver: int = 0, with_noise: bool = False):
    """Every source alone, float32 [S, C, T], as it sounds in the scene to receiver
    ``receiver`` (0: ``recipe.array``, k: ``recipe.receivers[k - 1]``); and whether their
    sum, with the noise, matches ``mixture`` (the stored audio, when given) within
    :data:`MATCH_TOLERANCE`. ``roots``: where the files of a recipe read ``as_stored`` are
    (:func:`dataset_roots`; a recipe from :func:`scene_recipe` names them already).
    ``with_noise``: also return the scene's noise as mixed ([C, T], or None without
    ``[noise]``)."""
    roots = roots or Roots()
    gone = _first_missing(recipe, roots)
    if gone:
        raise DatasetError(f"{gone}, which the recipe of {recipe.scene_id} names, is not there; a plan names "
                           f"clips relative to its corpus: take the recipe from scene_recipe(DATASET_DIR, ...), "
                           f"or pass roots=dataset_roots(DATASET_DIR)")
    parts = mix_parts(roots.resolve(recipe))
    stems = parts.stems(receiver)
    mix = parts.mix if receiver == 0 else parts.others[receiver - 1][1]
    same = mixture is None or float(np.max(np.abs(mix - mixture))) <= MATCH_TOLERANCE
    return (stems, same, parts.noise_stem(receiver)) if with_noise else (stems, same)


def _first_missing(recipe: SceneRecipe, roots: Roots) -> str | None:
    """The first file ``recipe`` reads that is not where ``roots`` say, as the recipe names it."""
    gone = missing_inputs(input_stats(roots.inputs([recipe])))
    return gone[0] if gone else None


def stem_paths(base: str, n_sources: int, noise: bool) -> list[str]:
    """Where :func:`write_stems` puts the previews of a scene of ``n_sources`` (and its
    ``noise``), beside the mixture written to ``base``: ``BASE.target.stereo.wav``,
    ``BASE.interferer1.stereo.wav``, ..., ``BASE.noise.stereo.wav``."""
    stem = os.path.splitext(base)[0]
    names = ["target" if k == 0 else f"interferer{k}" for k in range(n_sources)]
    return [f"{stem}.{name}.stereo.wav" for name in names + (["noise"] if noise else [])]


def write_stems(root: str, scene, base: str, corpus_dir: str | None = None,
                bank: str | None = None) -> tuple[list[str], bool]:
    """Write a headphone preview of each source alone next to ``base`` (a WAV path):
    ``BASE.target.stereo.wav``, ``BASE.interferer1.stereo.wav``, ... Returns the paths
    and whether the stems match the stored mixture (False: the clips changed since)."""
    recipe = scene_recipe(root, scene.split, scene.index, scene.scene_id, as_stored=True)
    roots = dataset_roots(root, corpus_dir, bank)
    gone = _first_missing(recipe, roots)
    if gone:
        flag = "--bank" if recipe.bank is not None and gone == recipe.bank.path else "--corpus-dir"
        raise DatasetError(f"the stems are rendered from the clips and {gone} is not where the plan says; pass "
                           f"{flag} with where it is now")
    poses = (recipe.array, *recipe.receivers)
    which = next((k for k, p in enumerate(poses) if p.format == scene.format), 0)  # the receiver the scene was read for
    stems, same, noise = render_stems(recipe, scene.audio, roots, which, with_noise=True)
    # what is not a source (ambience, diffuse noise, babble, sensor noise) comes last
    parts = [*stems[:len(recipe.sources)], *([noise] if noise is not None else [])]
    paths = stem_paths(base, len(recipe.sources), noise is not None)
    for path, part in zip(paths, parts):
        save_wav(path, stereo_preview(part, poses[which].format, poses[which].mics()).T, recipe.fs)
    return paths, same
