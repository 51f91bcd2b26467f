"""Each source of a stored scene alone: rendered again from the scene's recipe.

A dataset keeps only the mixture. Its plan (``plan/{split}.jsonl``) holds the recipe of
every scene, and a recipe determines its scene, so the renderer can give the target
alone and each interferer alone, exactly as they sound in the mix (same RIRs, gains and
anti-clipping gain: the stems add up to the stored mixture). ``tsel inspect --wav``
writes them as headphone previews (:mod:`tsel_data.stereo`).

This needs what rendering needs: the plan file and the clips (and the RIR bank) the
recipe names, where the plan says they are (relative to the dataset folder), or where
``corpus_dir`` and ``bank`` say.
"""
from __future__ import annotations

import os

import numpy as np

from .audio import save_wav
from .errors import DatasetError
from .plan import plan_roots
from .recipe import Roots, SceneRecipe
from .render import mix_parts
from .shards import plan_config
from .stereo import stereo_preview
from .store.integrity import input_stats, missing_inputs
from .store.layout import Layout
from .store.plans import read_plan_lines

# The stored mixture and the one rendered again agree to float32 rounding; more means the
# clips or the bank changed since the dataset was made.
MATCH_TOLERANCE = 1e-4


def scene_recipe(root: str, split: str, index: int, scene_id: str) -> SceneRecipe:
    """The recipe of scene ``index`` of ``split`` from the dataset's plan."""
    layout = Layout(root)
    lines = read_plan_lines(layout, split)
    if index >= len(lines):
        raise DatasetError(f"{layout.plan_file(split)} has no recipe for {scene_id} (the plan is missing or "
                           f"shorter); the stems are rendered from the scene's recipe")
    recipe = SceneRecipe.from_json(lines[index])
    if recipe.scene_id != scene_id:
        raise DatasetError(f"{layout.plan_file(split)}: line {index + 1} is {recipe.scene_id}, not {scene_id}; the "
                           f"plan does not belong to these shards")
    return recipe


def dataset_roots(root: str, corpus_dir: str | None = None, bank: str | None = None) -> Roots:
    """Where the files of a dataset's recipes are: as its plan says, or as given."""
    return plan_roots(plan_config(root, corpus_dir, bank), Layout(root))


def render_stems(recipe: SceneRecipe, mixture: np.ndarray | None = None,
                 roots: Roots | None = None, receiver: int = 0, with_noise: bool = False):
    """Every source alone, float32 [S, C, T], as it sounds in the scene to receiver
    ``receiver`` (0: ``recipe.array``, k: ``recipe.receivers[k - 1]``); and whether their
    sum, with the noise, matches ``mixture`` (the stored audio, when given) within
    :data:`MATCH_TOLERANCE`. ``roots``: where the recipe's files are. ``with_noise``: also
    return the scene's noise as mixed ([C, T], or None without ``[noise]``)."""
    parts = mix_parts((roots or Roots()).resolve(recipe))
    stems = parts.stems(receiver)
    mix = parts.mix if receiver == 0 else parts.others[receiver - 1][1]
    same = mixture is None or float(np.max(np.abs(mix - mixture))) <= MATCH_TOLERANCE
    return (stems, same, parts.noise_stem(receiver)) if with_noise else (stems, same)


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
    recipe = scene_recipe(root, scene.split, scene.index, scene.scene_id)
    roots = dataset_roots(root, corpus_dir, bank)
    gone = missing_inputs(input_stats(roots.inputs([recipe])))
    if gone:
        flag = "--bank" if recipe.bank is not None and gone[0] == recipe.bank.path else "--corpus-dir"
        raise DatasetError(f"the stems are rendered from the clips and {gone[0]} is not where the plan says; pass "
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
