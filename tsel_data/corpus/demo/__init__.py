"""The built-in demo corpus: synthetic captioned clips, so everything runs offline.

>>> from tsel_data.corpus.demo import synth_corpus
>>> info = synth_corpus("demo-corpus", seed=0)   # ~90 clips, a few seconds
>>> info["csv"]["train"], info["audio_dir"]

See :mod:`tsel_data.corpus.demo.synth` for the layout and :mod:`tsel_data.corpus.demo.sounds` for
the sound models.
"""
from .sounds import SOUND_TYPES, TYPES_BY_NAME, SoundType
from .synth import (CAPTIONS_PER_CLIP, CSV_HEADER, SPLITS, ClipFormat, ClipSpec, corpus_files, plan_corpus,
                    render_clip, synth_corpus, youtube_id)

__all__ = [
    "SOUND_TYPES", "TYPES_BY_NAME", "SoundType", "CAPTIONS_PER_CLIP", "CSV_HEADER",
    "SPLITS", "ClipFormat", "ClipSpec", "corpus_files", "plan_corpus", "render_clip", "synth_corpus",
    "youtube_id",
]
