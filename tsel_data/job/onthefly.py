"""Scenes rendered on demand, for trainers: the planner and renderer of ``tsel generate``,
without the shards.

>>> from tsel_data.job.onthefly import scene_source
>>> scenes = scene_source(preset="demo", split="train", home="/tmp/tsel-home")
>>> s = scenes[3]          # a tsel_data.store.reader.Scene, as open_dataset gives it
>>> scenes.set_epoch(1)    # new scenes, drawn from (seed, epoch, index)

Scene *i* of a split at epoch 0 is **bit for bit** scene *i* of the dataset ``tsel
generate`` makes from the same config and corpus: the same recipe (same planner, same
catalog of checked clips), the same renderer, the same float32 audio, labels and record.
Epoch *e* > 0 draws other scenes: it is the dataset of seed :func:`epoch_seed`\\ (seed,
*e*), so any epoch can be written to disk with ``tsel generate --seed``. Every draw
comes from (seed, epoch, split, index): no global random state, the same scenes for any
number of workers.

A :class:`SceneSource` pickles to its config, the split's checked clips and the bank
path; every process (fork or spawn, e.g. DataLoader workers) renders on its own and
opens the clips and the bank itself.
"""
from __future__ import annotations

import tempfile
from dataclasses import replace

import numpy as np

from ..config import Config, load_config
from ..config.receiver import array_pose
from ..errors import ConfigError
from ..plan.drawn import exclude_every_bad_clip
from ..plan.sampler import prepare_views, plan_scene
from ..render.mix import render_scene
from ..scene.recipe import SceneRecipe
from ..store.layout import Layout
from ..store.reader import Scene


def epoch_seed(seed: int, epoch: int) -> int:
    """The dataset seed whose scenes epoch ``epoch`` of a dataset of seed ``seed`` draws.

    Epoch 0 is the dataset itself; later epochs take a seed mixed from both numbers
    (numpy's SeedSequence), so epochs never repeat each other or other seeds' epoch 0.
    """
    if epoch < 0:
        raise ValueError(f"epoch must be >= 0, got {epoch}")
    if epoch == 0:
        return int(seed)
    return int(np.random.SeedSequence([int(seed), int(epoch)]).generate_state(1, np.uint32)[0])


class SceneSource:
    """The scenes of one split of a config, rendered when asked for.

    Parameters
    ----------
    cfg : Config
        The dataset config (as ``tsel generate`` would use it).
    split : str
        A split of the config with scenes (``splits.NAME.count`` > 0 gives ``len``).
    home : str, optional
        Where built-in inputs are made once (the ``builtin:demo`` corpus and
        ``builtin:demo-bank``), as ``tsel generate`` makes them in its ``--out`` folder;
        a temporary folder when None. Give the dataset folder of a generated dataset to
        get its exact records (they name the clips' paths).
    workers : int
        Processes for checking the clips once, here.
    epoch : int
        The epoch drawn from (see :meth:`set_epoch`).

    ``len(source)``, ``source[i]`` (a :class:`~tsel_data.store.reader.Scene`),
    ``source.recipe(i)``, iteration. ``source.get(i, epoch=e)`` reads another epoch
    without changing the current one.
    """

    def __init__(self, cfg: Config, split: str, home: str | None = None, workers: int = 1, epoch: int = 0):
        if split not in cfg.splits or not cfg.splits[split].count:
            have = ", ".join(s for s in cfg.active_splits()) or "none"
            raise ConfigError(f"split {split!r} makes no scenes in config {cfg.name}; splits with scenes: {have}")
        layout = Layout(home or tempfile.mkdtemp(prefix="tsel-scenes-"))
        _, views = prepare_views(cfg, layout, workers)
        if cfg.corpus.check == "drawn":  # any scene may be asked for: every clip checked, as a drawn plan ends up
            exclude_every_bad_clip(cfg, views[split], workers)
        self.cfg, self.split, self.view = cfg, split, views[split]
        self.home = layout.root
        self.fs, self.label_hop, self.format = cfg.audio.fs, cfg.audio.label_hop, cfg.scene.format
        self.channel_names = list(array_pose(cfg).channel_names())
        self.epoch = 0
        self.set_epoch(epoch)

    @property
    def seed(self) -> int:
        """The dataset seed (epoch 0's)."""
        return self.cfg.seed

    @property
    def caption_similarity(self) -> float:
        """The ambiguity guard the scenes are planned with (``scene.caption_similarity``)."""
        return self.cfg.scene.caption_similarity

    @property
    def similarity(self) -> str:
        """The caption similarity the scenes are planned with (``scene.similarity``)."""
        return str(self.cfg.scene.similarity)

    def set_epoch(self, epoch: int) -> None:
        """Draw scenes of epoch ``epoch`` from now on (0: the dataset's own scenes)."""
        self._epoch_cfg = replace(self.cfg, seed=epoch_seed(self.cfg.seed, epoch))
        self.epoch = int(epoch)

    def __len__(self) -> int:
        return self.cfg.splits[self.split].count

    def _index(self, i: int) -> int:
        n = len(self)
        if i < 0:
            i += n
        if not 0 <= i < n:
            raise IndexError(f"scene index {i} out of range for split {self.split!r} with {n} scenes")
        return i

    def recipe(self, i: int, epoch: int | None = None) -> SceneRecipe:
        """The recipe of scene ``i`` (of the current epoch, or of ``epoch``)."""
        cfg = self._epoch_cfg if epoch is None else replace(self.cfg, seed=epoch_seed(self.cfg.seed, epoch))
        return plan_scene(cfg, self.split, self._index(int(i)), self.view)

    def get(self, i: int, epoch: int | None = None) -> Scene:
        """Scene ``i`` rendered now, as the offline reader returns it."""
        return render_scene(self.recipe(i, epoch), self.view.roots)

    def __getitem__(self, i: int) -> Scene:
        return self.get(int(i))

    def __iter__(self):
        for i in range(len(self)):
            yield self.get(i)

    def __repr__(self) -> str:
        return (f"SceneSource(config={self.cfg.name!r}, split={self.split!r}, scenes={len(self)}, "
                f"epoch={self.epoch}, format={self.format!r})")


def scene_source(preset: str | None = None, config: str | None = None, split: str = "train", *,
                 home: str | None = None, workers: int = 1, epoch: int = 0, overrides=(), **shortcuts) -> SceneSource:
    """A :class:`SceneSource` from a preset and/or a TOML config, as ``tsel generate``
    loads them: ``overrides`` are ``--set`` strings; ``shortcuts`` are ``corpus_dir``,
    ``bank``, ``seed`` and ``splits`` ({name: count}) of :func:`~tsel_data.config.load_config`."""
    cfg = load_config(preset=preset, path=config, overrides=overrides, **shortcuts)
    return SceneSource(cfg, split, home=home, workers=workers, epoch=epoch)
