"""The small configs of the datasets the tests generate, by name: one place to read what
each suite builds, and the key of the session's cache of generated datasets (a name is
built once per run, whichever worker asks first; conftest's ``generated_dataset``)."""
from __future__ import annotations

from dataclasses import dataclass, field

# a fast config over the demo corpus: 3 s scenes, few per split (the ``small_config`` fixture)
SMALL = ["audio.duration=3.0", "output.shard_size=4", 'room.rt60=["uniform", 0.3, 0.5]']
# shorter and drier still: 1 s scenes in shards of 2
TINY = ["audio.duration=1.0", "output.shard_size=2", 'room.rt60=["uniform", 0.2, 0.3]']


@dataclass(frozen=True)
class DatasetConfig:
    preset: str = "demo"
    splits: dict = field(default_factory=lambda: {"train": 6, "val": 2, "test": 2})
    overrides: tuple = ()
    corpus: str = "demo"  # or "recordings": the STARSS23 stand-in (the demo_recordings fixture)

    def load(self, corpus_dir: str):
        from tsel_data.config import load_config

        return load_config(preset=self.preset, corpus_dir=corpus_dir, splits=dict(self.splits),
                           overrides=list(self.overrides))


DATASETS = {
    # end to end through the library: every split, both scenarios (job/test_pipeline)
    "small": DatasetConfig(splits={"train": 6, "val": 2, "test": 3}, overrides=tuple(SMALL)),
    # checks, tampering, full disks and resumes (e2e/test_reliability)
    "tiny": DatasetConfig(splits={"train": 4, "val": 2, "test": 2}, overrides=tuple(TINY)),
    # plan seals: half-second scenes at 8 kHz (store/test_plan_seal)
    "sealed": DatasetConfig(splits={"train": 4, "val": 0, "test": 2},
                            overrides=("audio.duration=0.5", "audio.fs=8000", "output.shard_size=2",
                                       'room.rt60=["uniform", 0.15, 0.2]')),
    # four 1 s train scenes in shards of 3, the last one partial (e2e/test_first_day)
    "partial-shard": DatasetConfig(splits={"train": 4, "val": 0, "test": 0},
                                   overrides=("audio.duration=1.0", "output.shard_size=3")),
    # scenes on demand against the stored ones (job/test_onthefly)
    "onthefly": DatasetConfig(splits={"train": 6, "val": 0, "test": 2},
                              overrides=("audio.duration=2.0", "output.shard_size=4")),
    # stems of stored scenes (job/test_stems)
    "stems": DatasetConfig(splits={"train": 0, "val": 0, "test": 3},
                           overrides=("audio.duration=1.0", "audio.fs=16000", "output.shard_size=4")),
    # moving sources from the demo bank, rooms split by split (render/test_motion)
    "moving": DatasetConfig(preset="demo-moving", splits={"train": 8, "val": 3, "test": 3},
                            overrides=("audio.duration=2.0", "output.shard_size=4")),
    # one scene heard by several receivers (render/test_several_receivers)
    "several-receivers": DatasetConfig(splits={"train": 3, "val": 0, "test": 2},
                                       overrides=("audio.duration=2.0", "output.shard_size=3",
                                                  'scene.scenario="two-directional"',
                                                  'scene.receivers=["foa", "tetra", "respeaker-6"]')),
    # relational and composite queries, same-kind distractors, onsets (plan/test_pairing)
    "extended-queries": DatasetConfig(splits={"train": 8, "val": 0, "test": 0},
                                      overrides=("audio.duration=2.0", "output.shard_size=4",
                                                 'scene.similarity="tfidf"',
                                                 'scene.query=["choose", ["caption", "relational", "composite"]]',
                                                 "scene.same_kind_distractors=0.2",
                                                 'scene.onset=["uniform", 0.0, 1.0]')),
    # long enough to stop mid-run: 3 s ISM scenes in a reverberant room (e2e/test_signals)
    "signals": DatasetConfig(splits={"train": 10, "val": 0, "test": 0},
                             overrides=("audio.duration=3.0", "output.shard_size=2", 'room.rir_method="ism"',
                                        'room.rt60=["uniform", 0.9, 1.0]')),
    # spatial captions and questions (export/test_spatial_language): static and moving (arcs and lines),
    # two or three sources, additive ones, later onsets, diffuse noise, rooms from dry to reverberant
    "language": DatasetConfig(splits={"train": 10, "val": 0, "test": 4},
                              overrides=("audio.duration=3.0", "output.shard_size=7", 'scene.motion="mixed"',
                                         'scene.path=["choose", ["arc", "line"]]', "scene.speed=40.0",
                                         'scene.interferers=["choose", [1, 2]]',
                                         'scene.scenario=["choose", ["two-directional", "directional+additive"]]',
                                         'scene.onset=["uniform", 0.0, 1.5]', 'noise.diffuse="pink"',
                                         'room.rt60=["uniform", 0.15, 1.2]')),
    # STARSS23's layout, recorded scenes of every window (e2e/test_recorded)
    "recorded": DatasetConfig(preset="starss23", splits={"train": 1000, "test": 1000}, corpus="recordings"),
    # each audio coding (store/test_store)
    **{f"coded-{c}": DatasetConfig(splits={"train": 3, "val": 0, "test": 0},
                                   overrides=("audio.duration=1.0", "output.shard_size=2", f'output.audio="{c}"'))
       for c in ("float32", "int16", "flac")},
}
